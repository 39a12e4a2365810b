"""The imaging modality a volume file's header names: ``"CT"``, ``"MR"`` or another DICOM
modality code, read where each format keeps it.

* DICOM: the Modality tag (0008,0060) (read by :mod:`hwsim.volumes.dicom`).
* NRRD: a ``modality:=`` key-value pair (its value, as written), else the ``content``
  field, else the header's ``#`` comments, searched for the words ``CT`` or ``MR``/``MRI``
  (or ``computed tomography``, ``magnetic resonance``).
* NIfTI: no modality field; its ``descrip`` and ``intent_name`` are searched the same way.

A text naming both CT and MR names neither.  The ``auto`` transfer preset reads the result
(:mod:`hwsim.spec.preset_choice`); the rule is in ``docs/scenes.md``.

# Ref: DICOM PS3.3 C.7.3.1.1.1 (Modality); NRRD format 5 (content, key/value pairs,
# comments); NIfTI-1 header (descrip, intent_name).
"""

from __future__ import annotations

import re
from pathlib import Path

__all__ = ["modality_in_text", "nrrd_modality", "nifti_modality"]

#: Words that name each modality in free text (case-sensitive acronyms, any-case phrases).
_WORDS = {
    "CT": re.compile(r"\bCT\b|(?i:\bcomputed tomography\b)"),
    "MR": re.compile(r"\bMRI?\b|(?i:\bmagnetic resonance\b)"),
}
#: Header lines read for comments at most (a NRRD header is a few dozen lines).
_MAX_HEADER_LINES = 256


def modality_in_text(text: str) -> str:
    """``"CT"`` or ``"MR"`` if ``text`` names exactly one of them as a word, else ``""``."""
    found = [name for name, words in _WORDS.items() if words.search(text)]
    return found[0] if len(found) == 1 else ""


def nrrd_modality(header: dict, path: Path) -> tuple[str, str]:
    """``(modality, where)`` a NRRD header names (``("", "")``: none)."""
    for key, value in header.items():
        if str(key).strip().lower() == "modality" and str(value).strip():
            return str(value).strip().upper(), "NRRD header modality"
    found = modality_in_text(str(header.get("content", "")))
    if found:
        return found, "NRRD header content"
    found = modality_in_text(" ".join(_nrrd_comments(path)))
    return (found, "NRRD header comment") if found else ("", "")


def nifti_modality(header) -> tuple[str, str]:
    """``(modality, where)`` a NIfTI header's ``descrip`` or ``intent_name`` names."""
    for key in ("descrip", "intent_name"):
        try:
            raw = header[key]
        except (KeyError, ValueError):
            continue
        value = raw.item() if hasattr(raw, "item") else raw
        text = value.decode("latin-1") if isinstance(value, bytes) else str(value)
        found = modality_in_text(text)
        if found:
            return found, f"NIfTI {key}"
    return "", ""


def _nrrd_comments(path: Path) -> list[str]:
    """The ``#`` comment lines of a NRRD header (pynrrd drops them)."""
    out = []
    try:
        with open(path, "rb") as fh:
            for _ in range(_MAX_HEADER_LINES):
                line = fh.readline(4096).decode("latin-1").strip()
                if not line:  # the blank line ends the header
                    break
                if line.startswith("#"):
                    out.append(line[1:].strip())
    except OSError:
        return []
    return out
