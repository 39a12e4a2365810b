"""hwsim figures: each machine's published figures against every timing rung."""

from __future__ import annotations

import json

import pytest

from hwsim.cli.commands import main
from hwsim.report.report import write_report
from hwsim.run.fidelity import builtin_archs, render, resolve_arch
from hwsim.studies.figures import figure_scene, figure_size, measure_figures

pytestmark = pytest.mark.system

CUBE4 = """schema = 1
name = "tiny-cube4"
[pipeline]
order = "slice-parallel"
count = 2
clock_hz = 1e6
[limits]
voxel_bits = [8, 12, 16]
max_volume = [16, 16, 16]
[published]
fps_8 = {fps8}
seconds_16 = 1.0
samples_per_second = 1.5e6
tolerance = {{ fps_8 = 0.01 }}
notes = {{ seconds_16 = "a note" }}
evidence = {{ fps_8 = "prediction", seconds_16 = "prediction", samples_per_second = "prediction" }}
"""


@pytest.fixture()
def tiny(tmp_path):
    path = tmp_path / "tiny.toml"
    path.write_text(CUBE4.format(fps8=100.0))
    return path


def test_figure_sizes_follow_the_keys():
    vp1000 = builtin_archs()["volumepro1000"]
    assert figure_size(vp1000, "fps_512") == 512
    assert figure_size(vp1000, "samples_per_second") == 256  # the smallest scenario
    assert figure_size(builtin_archs()["cube4-teramac"], "seconds_128") == 128
    assert figure_size(vp1000, "voxels_per_axis") is None
    assert figure_size(builtin_archs()["vizard2"], "samples_per_second") is None  # none there


@pytest.mark.parametrize("name", sorted(builtin_archs()))
def test_the_dense_scenario_takes_one_sample_per_voxel_on_every_machine(name):
    run = render(figure_scene(8), fidelity="functional", arch=name)
    assert run.samples == 8**3


def test_rows_are_the_rungs_own_cycle_counts(tiny):
    arch = resolve_arch(str(tiny))
    rows = measure_figures([arch], ("functional", "cycle"), max_size=8)
    by = {(r.figure, r.rung): r for r in rows}
    cyc = by["fps_8", "cycle"]
    direct = render(figure_scene(8), fidelity="cycle", arch=arch)
    assert cyc.status == "ok" and cyc.cycles == direct.cycles
    assert cyc.simulated == pytest.approx(1e6 / direct.cycles)
    assert cyc.difference == pytest.approx(cyc.simulated / 100.0 - 1.0)
    assert cyc.within is (abs(cyc.difference) <= 0.01)
    sps = by["samples_per_second", "functional"]
    assert sps.samples == 8**3 and sps.simulated == pytest.approx(512 * 1e6 / sps.cycles)
    assert sps.tolerance is None and sps.within is None
    # 16^3 is above --max-size: skipped with the reason, the file's note kept.
    skipped = by["seconds_16", "cycle"]
    assert skipped.status == "skipped" and "max-size 8" in skipped.note
    assert "a note" in skipped.note


def test_progress_counts_the_planned_voxels_up_to_the_total(tiny):
    """The figures bar: monotone, ends at its total (8^3 voxels per rung; 16^3 is skipped)."""
    calls = []
    measure_figures(
        [resolve_arch(str(tiny))],
        ("functional", "cycle"),
        max_size=8,
        progress=lambda d, t, what: calls.append((d, t, what)),
    )
    done = [d for d, _, _ in calls]
    assert {t for _, t, _ in calls} == {2 * 8**3}
    assert done == sorted(done) and done[-1] == 2 * 8**3 and 0 < done[len(done) // 2] < 2 * 8**3
    assert {w for _, _, w in calls} == {
        "tiny-cube4 functional dense head 8^3",
        "tiny-cube4 cycle dense head 8^3",
    }


def test_a_figure_inside_or_outside_its_band(tmp_path):
    arch = resolve_arch(str(_tiny(tmp_path, 100.0)))
    (row,) = [r for r in measure_figures([arch], ("cycle",), max_size=8) if r.figure == "fps_8"]
    inside = _tiny(tmp_path, row.simulated * 1.005, "b")
    outside = _tiny(tmp_path, row.simulated * 1.05, "c")
    for path, expected in ((inside, True), (outside, False)):
        got = measure_figures([resolve_arch(str(path))], ("cycle",), max_size=8)
        assert next(r for r in got if r.figure == "fps_8").within is expected


def _tiny(tmp_path, fps8: float, tag: str = "a"):
    path = tmp_path / f"tiny-{tag}.toml"
    path.write_text(CUBE4.format(fps8=fps8))
    return path


def test_cli_writes_the_table_and_the_report_shows_it(tiny, tmp_path):
    out = tmp_path / "fig"
    args = ["figures", "--arch", str(tiny), "--rungs", "functional,cycle", "--max-size", "8"]
    assert main([*args, "--out", str(out), "--quiet"]) == 0
    data = json.loads((out / "figures.json").read_text())
    assert {r["rung"] for r in data["rows"]} == {"functional", "cycle"}
    assert (out / "figures.csv").read_text().startswith("arch,figure,published")
    md = (out / "figures.md").read_text()
    assert "| tiny-cube4 | fps_8 | prediction | 100 | dense head 8^3 |" in md
    run = tmp_path / "run"
    render_args = ["render", "--phantom", "head:size=12", "--image", "12", "--quiet"]
    assert main([*render_args, "--fidelity", "functional", "--out", str(run)]) == 0
    paths = write_report([run, out], tmp_path / "report")
    text = paths["md"].read_text()
    assert "## Published figures of every machine" in text
    assert "| tiny-cube4 | fps_8 |" in text


def test_bad_rung_and_size_are_refused(tiny, tmp_path, capsys):
    assert main(["figures", "--rungs", "golden", "--out", str(tmp_path / "x")]) == 2
    assert "--rungs" in capsys.readouterr().err
    assert main(["figures", "--max-size", "0", "--out", str(tmp_path / "y")]) == 2
    assert "--max-size" in capsys.readouterr().err


@pytest.mark.parametrize("rung", ["cycle", "transaction"])
def test_timing_rungs_report_the_back_to_back_period_where_they_time_one(tmp_path, rung):
    import re
    from pathlib import Path

    from hwsim.run.fidelity import builtin_archs as archs

    body = Path(archs()["volumepro500"].source).read_text()
    body = re.sub(
        r"\[published\].*?\n\[memory\]",
        '[published]\nfps_16 = 1000.0\nevidence = { fps_16 = "prediction" }\n\n[memory]',
        body,
        flags=re.S,
    )
    body = body.replace('name = "volumepro500"', 'name = "vp500-16"')
    path = tmp_path / "vp500-16.toml"
    path.write_text(body)
    arch = resolve_arch(str(path))
    (row,) = measure_figures([arch], (rung,), max_size=16)
    run = render(figure_scene(16), fidelity=rung, arch=arch, steady_state=True)
    period = run.counters["frame.period_cycles"]
    assert row.basis == "frame period" and row.cycles == run.cycles
    assert row.simulated == pytest.approx(arch.clock_hz / period)
    assert row.single_frame == pytest.approx(arch.clock_hz / run.cycles)
    assert period <= run.cycles  # the next frame's fill overlaps this one's drain
    assert "back-to-back" in row.note


def test_back_to_back_frames_only_where_a_machine_times_them():
    from hwsim.core.errors import InputError

    scene = figure_scene(8)
    with pytest.raises(InputError, match="steady_state"):
        render(scene, fidelity="functional", arch="volumepro500", steady_state=True)
    with pytest.raises(InputError, match="cube4 .slice-parallel order. times single frames"):
        render(scene, fidelity="cycle", arch="cube4", steady_state=True)


def test_a_cache_hit_rate_figure_is_read_off_the_rungs_counters(tmp_path):
    """A [[published.measured]] figure of the block cache: the cycle and transaction
    rungs' own cache.hits / cache.lookups; the functional rung has no cache."""
    import re
    from pathlib import Path

    body = Path(builtin_archs()["vizard2"].source).read_text()
    body = body[: body.index("[published]")] + (
        '[published]\n[[published.measured]]\nname = "hits"\ncache_hit_rate = 0.98\n'
        'volume = [16, 16, 16]\nkind = "simulated"\nsource = "[V] a paper"\n'
    )
    body = re.sub(r'name = "vizard2"', 'name = "v2-16"', body)
    path = tmp_path / "v2-16.toml"
    path.write_text(body)
    arch = resolve_arch(str(path))
    rows = {r.rung: r for r in measure_figures([arch], ("functional", "cycle"), max_size=16)}
    assert rows["functional"].status == "not modelled"
    cycle = rows["cycle"]
    from hwsim.spec.published import Scenario
    from hwsim.studies.figures import figure_machine

    direct = render(
        figure_scene(Scenario((16, 16, 16))), fidelity="cycle", arch=figure_machine(arch)
    )
    hits, lookups = direct.counters["cache.hits"], direct.counters["cache.lookups"]
    assert lookups > 0 and cycle.status == "ok"
    assert cycle.simulated == pytest.approx(hits / lookups)
    assert cycle.difference == pytest.approx(hits / lookups / 0.98 - 1)
    assert cycle.evidence == "prediction" and cycle.kind == "simulated"


def test_leave_one_out_fits_the_clock_on_one_figure_and_predicts_the_other(tiny):
    """Cycles do not depend on the clock: fitting f on fps_8 predicts samples_per_second
    at 8^3 as (its cycles) at that clock, by the rung's own counts."""
    from hwsim.studies.figures import leave_one_out

    arch = resolve_arch(str(tiny))
    rows = measure_figures([arch], ("cycle",), max_size=8)
    loo = leave_one_out(rows, {arch.name: arch.clock_hz})
    fit = next(r for r in loo if r.fitted_on == "fps_8" and r.figure == "samples_per_second")
    fps8 = next(r for r in rows if r.figure == "fps_8")
    assert fit.clock_hz == pytest.approx(100.0 * fps8.used_cycles)  # 100 fps = f / cycles
    assert fit.predicted == pytest.approx(8**3 * fit.clock_hz / fps8.used_cycles)
    assert fit.difference == pytest.approx(fit.predicted / 1.5e6 - 1)
    assert all(r.figure != "seconds_16" for r in loo)  # skipped rows predict nothing
