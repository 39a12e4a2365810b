"""What the report's tables and plots show a reader (issue 32): only the units the run's
machine has, a unit on every number, stall labels that do not collide, and tables that fit
the page."""

from __future__ import annotations

import json
import re

import pytest

from hwsim.cli.commands import main
from hwsim.report import plots
from hwsim.report.report import write_report

pytestmark = pytest.mark.system


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("runs")
    common = ["--phantom", "head:size=24", "--image", "24", "--fidelity", "cycle", "--quiet"]
    for arch in ("cube4", "volumepro500"):
        assert main(["render", *common, "--arch", arch, "--out", str(root / arch)]) == 0
    return root


@pytest.fixture(scope="module")
def report(runs, tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    paths = write_report([runs / "cube4", runs / "volumepro500"], out)
    return paths, paths["md"].read_text(), paths["html"].read_text()


def _area_rows(md: str, run: int) -> list[str]:
    section = md.split(f"\n## Run {run}:")[1].split("\n## ")[0]
    table = section.split("| unit | table logic mm^2 |")[1].split("\n\n")[0]
    return [line.split(" | ")[0].strip("| ") for line in table.splitlines()[2:]]


def test_area_two_ways_lists_only_the_units_the_machine_has(runs, report):
    cube4 = json.loads((runs / "cube4" / "stats.json").read_text())
    assert cube4["shading"] == "phong"
    shade = cube4["area"]["units"]["shade"]
    assert shade["synthesized"] is None and "phong here, reflectance-map" in shade["rtl_differs"]
    _, md, _ = report
    assert "shade" not in _area_rows(md, 1)
    assert "Not compared two ways, the RTL being another kind of unit: shade (" in md
    # VolumePro 500 shades with reflectance maps, as the RTL does: compared.
    assert "shade" in _area_rows(md, 2) and "interp" in _area_rows(md, 1)


def _overlaps(boxes) -> list[tuple[int, int]]:
    return [
        (i, j)
        for i, a in enumerate(boxes)
        for j, b in enumerate(boxes[i + 1 :], start=i + 1)
        if a.overlaps(b)
    ]


@pytest.mark.parametrize("scale", [4_024.0, 734_567.0, 3_345_678.0])
def test_stall_plot_labels_do_not_overlap(monkeypatch, tmp_path, scale):
    """Forty units of a wide machine, long memory paths, stall counts of every size."""
    units = {
        f"pipeline[{p}].{u}": {"stall": scale + p, "stall:input-empty": scale / 7}
        for p in range(8)
        for u in ("interp", "gradient", "classify", "shade", "composite")
    }
    units["memory.sdram.controller_with_a_long_name[3].bank_queue"] = {"stall:refresh": scale}
    figures = []
    monkeypatch.setattr(plots, "_save", lambda fig, path: figures.append(fig) or path)
    assert plots.plot_stalls(units, tmp_path / "s.png") is not None
    (fig,) = figures
    renderer = fig.canvas.get_renderer()
    fig.canvas.draw()
    (ax,) = fig.axes
    for axis in (ax.xaxis, ax.yaxis):
        boxes = [t.get_window_extent(renderer) for t in axis.get_ticklabels() if t.get_text()]
        assert len(boxes) >= 2 and not _overlaps(boxes)
    legend = ax.get_legend().get_window_extent(renderer)
    assert not legend.overlaps(ax.get_window_extent(renderer))  # beside the bars
    ylabels = [t.get_window_extent(renderer) for t in ax.yaxis.get_ticklabels()]
    assert not any(b.overlaps(ax.get_window_extent(renderer)) for b in ylabels)
    assert all(len(t.get_text()) <= 8 for t in ax.xaxis.get_ticklabels())


_NUMBER = re.compile(r"^[-+±]?[\d,]*\.?\d+(e[-+]?\d+)?%?( ok| OUT)?$")
#: What names a number's unit in a column header or a quantity's name.
_UNIT = re.compile(
    r"\b(s|MHz|fps|J|W|GE|GiB|dB|bits|cycles|samples|rays|levels|count|unit)\b|samples/s|mm\^2"
    r"|GB/s|%|/|error|diff|tolerance"
)


def _md_tables(md: str):
    for chunk in md.split("\n\n"):
        lines = [line for line in chunk.splitlines() if line.startswith("|")]
        if len(lines) >= 3:
            rows = [[c.strip() for c in line.strip("|").split(" | ")] for line in lines]
            yield rows[0], rows[2:]


def _unitless(md: str) -> list[tuple[str, str]]:
    """Numbers in the report's tables with no unit in their column or quantity name."""
    bare = []
    for header, body in _md_tables(md):
        if header[:2] == ["quantity", "value"]:
            bare += [(r[0], r[1]) for r in body if _NUMBER.match(r[1]) and not _UNIT.search(r[0])]
        elif "unit" not in header:  # a unit column names every line's
            for j, name in enumerate(header):
                cells = [r[j] for r in body if r[j] not in ("-", "")]
                numbers = cells and all(_NUMBER.match(c) for c in cells)
                if numbers and name != "run" and not _UNIT.search(name):
                    bare.append((name, cells[0]))
    return bare


def test_every_number_in_the_tables_carries_its_unit(report):
    _, md, _ = report
    assert "| clock (MHz) | 125 |" in md
    assert _unitless(md) == []
    figures = next(h for h, _ in _md_tables(md) if "scenario" in h)
    assert figures[figures.index("figure") + 1] == "unit"
    assert "| fps_256 | fps |" in md and "| samples_per_second | samples/s |" in md


def test_the_figures_table_fits_the_page(report):
    """Each rung's diff shares its cell, the notes are footnotes under the table and a
    table of many columns is set dense, so the tolerance and note columns are on the page
    rather than in a horizontal scroll."""
    _, md, html = report
    header, body = next((h, b) for h, b in _md_tables(md) if "scenario" in h)
    assert "diff" not in header and len(header) <= 12
    assert header[-2:] == ["tolerance", "note"]
    marks = [line[-1] for line in body]
    assert all(re.fullmatch(r"\[\d+\]", m) for m in marks if m) and any(marks)
    notes = html.split('<ol class="notes">')[1].split("</ol>")[0]
    assert notes.count("<li>") == max(int(m.strip("[]")) for m in marks if m)
    assert '<table class="dense">' in html


def test_the_slow_unit_flags_name_only_units_the_machine_has():
    """``hwsim archs`` flags units whose RTL misses the clock: the reflectance-map shader
    on VolumePro 500, which has it; never on Cube-4, whose shader is Phong.  Every unit
    meets the machines' own clocks (issue 34), so each machine runs at 200 MHz here."""
    import dataclasses

    from hwsim.energy import units_below_clock
    from hwsim.run.fidelity import resolve_arch

    def slow(name):
        arch = dataclasses.replace(resolve_arch(name), clock_hz=200e6)
        return dict(units_below_clock(arch))

    assert "shade" in slow("volumepro500")
    assert "shade" not in slow("cube4")
    assert "gradient" not in slow("volumepro1000")
