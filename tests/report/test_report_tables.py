"""What the report's tables and plots show a reader (issue 32): only the units the run's
machine has, a unit on every number, stall labels that do not collide, and tables that fit
the page."""

from __future__ import annotations

import json

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
