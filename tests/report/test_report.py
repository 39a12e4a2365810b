"""hwsim report: Markdown + self-contained HTML with images, counters and published figures."""

from __future__ import annotations

import re

import pytest

from hwsim.cli.commands import main
from hwsim.core.errors import InputError
from hwsim.report import plots
from hwsim.report.report import load_run, write_report

pytestmark = pytest.mark.system


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    root = tmp_path_factory.mktemp("runs")
    common = ["--phantom", "head:size=24", "--image", "24", "--quiet"]
    assert main(["render", *common, "--fidelity", "functional", "--out", str(root / "f")]) == 0
    assert main(["render", *common, "--arch", "volumepro500", "--out", str(root / "g")]) == 0
    trade = ["trade", "--arch", "volumepro500", "--rungs", "golden,functional"]
    assert main([*trade, "--image", "16", "--size", "16", "--out", str(root / "t"), "--quiet"]) == 0
    return root


@pytest.fixture(scope="module")
def report(folders, tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    paths = write_report([folders / "f", folders / "g", folders / "t"], out)
    return paths, paths["md"].read_text(), paths["html"].read_text()


def test_markdown_has_every_section_and_links_existing_pngs(report):
    paths, md, _ = report
    for heading in (
        "## Run 1: head / head: functional on volumepro500",
        "### Images",
        "### Unit utilisation and stalls",
        "### Memory bandwidth",
        "### Published figures",
        "## Fidelity-ladder trade",
    ):
        assert heading in md
    links = re.findall(r"!\[[^]]*\]\(([^)]+)\)", md)
    assert len(links) >= 3
    for link in links:
        assert (paths["md"].parent / link).read_bytes()[:4] == b"\x89PNG"


def test_absent_counters_are_not_recorded_not_invented(report):
    _, md, _ = report
    assert "Per-unit busy and stall counters: not recorded by the functional rung." in md
    assert "Memory traffic counters: not recorded by the functional rung." in md


def test_golden_pairs_with_the_run_at_the_same_positions(report, folders):
    _, md, _ = report
    run1 = md.split("## Run 2")[0]
    assert f"Reference: golden run {folders.joinpath('g').name}." in run1
    assert "Reference: the ideal ray caster" in md.split("## Run 2")[1]


def test_published_figures_compare_the_simulated_rate(report, folders):
    _, md, _ = report
    stats = load_run(folders / "f").stats
    ratio = stats["samples_per_second"] / 500e6  # VolumePro 500: 500 M samples/s [V]
    row = "| samples_per_second | samples/s | peak (pipeline.clock_hz) | 5e+08 | "
    assert row + f"{stats['samples_per_second']:.4g} | {ratio:.3f} |" in md


def test_html_is_self_contained(report):
    _, _, html = report
    sources = re.findall(r'src="([^"]*)"', html)
    assert sources and all(s.startswith("data:image/png;base64,") for s in sources)
    assert html.count("<table>") >= 4 and "<h1>hwsim report</h1>" in html


def test_unit_counters_feed_utilisation_and_stall_plots(tmp_path):
    counters = {
        "pipeline[0].interp.busy_cycles": 900,
        "pipeline[0].interp.stall.memory": 60,
        "pipeline[0].interp.stall.fifo_full": 40,
        "pipeline[0].shade": {"busy_cycles": 500, "stall_cycles": 10},
        "memory.sdram.read_bytes": 4096,
        "functional.samples": 7,
    }
    units = plots.unit_counters(counters)
    assert units == {
        "pipeline[0].interp": {"busy": 900.0, "stall:memory": 60.0, "stall:fifo_full": 40.0},
        "pipeline[0].shade": {"busy": 500.0, "stall": 10.0},
    }
    assert plots.plot_utilisation(units, 1000, tmp_path / "u.png").read_bytes()[:4] == b"\x89PNG"
    assert plots.plot_stalls(units, tmp_path / "s.png") is not None
    assert plots.memory_counters(counters) == {"memory.sdram.read_bytes": 4096.0}
    assert plots.plot_utilisation({}, 1000, tmp_path / "n.png") is None


def test_a_folder_that_is_not_a_run_is_bad_input(tmp_path, capsys):
    with pytest.raises(InputError, match="RUN_DIR: not a run folder: stats.json missing"):
        load_run(tmp_path)
    assert main(["report", str(tmp_path), "--out", str(tmp_path / "r")]) == 2
    assert "not a run folder" in capsys.readouterr().err
