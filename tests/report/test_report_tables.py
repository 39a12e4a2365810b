"""What the report's tables and plots show a reader (issue 32): only the units the run's
machine has, a unit on every number, stall labels that do not collide, and tables that fit
the page."""

from __future__ import annotations

import json

import pytest

from hwsim.cli.commands import main
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
