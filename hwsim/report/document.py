"""The report as a list of blocks, written as Markdown or as one self-contained HTML page.

A block is ``("h1" | "h2" | "h3" | "p", text)``, ``("table", header, rows)``,
``("notes", texts)`` (a table's numbered footnotes, ``[1]`` the first) or
``("img", png_path, alt)``; both writers take the same list, so the two files say the
same thing.  A table of many columns is set smaller in HTML and its cells wrap, so it fits
the page rather than scrolling.
"""

from __future__ import annotations

import base64
import html
from pathlib import Path

__all__ = ["Block", "markdown", "html_page"]

Block = tuple
#: Tables with more columns than this are set smaller in HTML (``table.dense``).
DENSE_COLUMNS = 9


def markdown(blocks: list[Block], out: Path) -> str:
    """Markdown; images are linked relative to ``out`` (the folder the file goes in)."""
    lines: list[str] = []
    for b in blocks:
        kind = b[0]
        if kind in ("h1", "h2", "h3"):
            lines += ["#" * int(kind[1]) + " " + b[1], ""]
        elif kind == "p":
            lines += [b[1], ""]
        elif kind == "table":
            header, rows = b[1], b[2]
            lines.append("| " + " | ".join(header) + " |")
            lines.append("|" + "---|" * len(header))
            lines += ["| " + " | ".join(c.replace("|", "\\|") for c in row) + " |" for row in rows]
            lines.append("")
        elif kind == "notes":
            lines += [f"{i}. {text}" for i, text in enumerate(b[1], start=1)] + [""]
        elif kind == "img":
            lines += [f"![{b[2]}]({Path(b[1]).relative_to(out)})", ""]
    return "\n".join(lines)


_CSS = """
body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em}
body{color:#222}table{border-collapse:collapse;margin:0.8em 0;font-size:0.85em}
th,td{border:1px solid #ccc;padding:3px 8px;text-align:left}th{background:#f0f0f0}
.wide{overflow-x:auto;max-width:100%}td{max-width:28em;overflow-wrap:break-word}
table.dense{font-size:0.72em}table.dense td,table.dense th{padding:2px 4px}
ol.notes{font-size:0.8em;color:#444}
img{max-width:100%;border:1px solid #eee;margin:0.4em 0}
h2{border-bottom:2px solid #ddd;margin-top:2em}"""


def html_page(blocks: list[Block], title: str) -> str:
    """One self-contained HTML page: inline CSS, images embedded as base64 PNG."""
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{html.escape(title)}</title>",
        f"<style>{_CSS}</style></head><body>",
    ]
    for b in blocks:
        kind = b[0]
        if kind in ("h1", "h2", "h3", "p"):
            parts.append(f"<{kind}>{html.escape(b[1])}</{kind}>")
        elif kind == "table":
            head = "".join(f"<th>{html.escape(c)}</th>" for c in b[1])
            body = "".join(
                "<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>"
                for row in b[2]
            )
            dense = ' class="dense"' if len(b[1]) > DENSE_COLUMNS else ""
            parts.append(
                f'<div class="wide"><table{dense}><thead><tr>{head}</tr></thead>'
                f"<tbody>{body}</tbody></table></div>"
            )
        elif kind == "notes":
            items = "".join(f"<li>{html.escape(text)}</li>" for text in b[1])
            parts.append(f'<ol class="notes">{items}</ol>')
        elif kind == "img":
            data = base64.b64encode(Path(b[1]).read_bytes()).decode()
            parts.append(f'<img alt="{html.escape(b[2])}" src="data:image/png;base64,{data}">')
    parts.append("</body></html>")
    return "\n".join(parts)
