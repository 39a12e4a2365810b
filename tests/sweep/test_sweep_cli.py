"""hwsim sweep end to end: the docs example, overrides that reach the model, resume, report."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from hwsim.cli.commands import main
from hwsim.studies.sweep import RunsDB

pytestmark = pytest.mark.system

DOCS = Path(__file__).resolve().parents[2] / "docs" / "sweeps.md"


@pytest.fixture(scope="module")
def swept(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("sweep")
    (example,) = re.findall(r"```toml\n(.*?)```", DOCS.read_text(), flags=re.S)
    (tmp / "sweep.toml").write_text(example)
    argv = ["sweep", str(tmp / "sweep.toml"), "--workers", "1", "--db", str(tmp / "runs.db")]
    assert main([*argv, "--out", str(tmp / "runs"), "--quiet"]) == 0
    with RunsDB(tmp / "runs.db") as db:
        rows = db.rows()
    return tmp, argv, rows


def test_the_docs_example_runs_every_combination_once(swept):
    _, _, rows = swept
    assert "That is 2 x 1 x 2 x 1 x 2 x 2 = 16 runs" in DOCS.read_text()
    assert len(rows) == 16 and all(r["status"] == "ok" for r in rows)
    combos = {
        (p["arch"], p["phantom"], p["pipelines"], p["formats.interp.weight_bits"])
        for p in (r["params"] for r in rows)
    }
    assert len(combos) == 16


def test_overrides_reach_the_model(swept):
    _, _, rows = swept
    by = {
        (
            r["params"]["arch"],
            r["params"]["phantom"],
            r["params"]["pipelines"],
            r["params"]["formats.interp.weight_bits"],
        ): r
        for r in rows
    }
    for (arch, phantom, pipes, bits), row in by.items():
        assert row["stats"]["arch"] == arch and row["clock_hz"] == 125e6
        if pipes == 1:
            four = by[arch, phantom, 4, bits]
            # Same samples, a quarter of the cycles (one sample per pipeline per clock).
            assert row["samples"] == four["samples"]
            assert row["cycles"] > 3.9 * four["cycles"]
        if bits == 6 and phantom.startswith("head"):
            assert row["image_sha256"] != by[arch, phantom, pipes, 8]["image_sha256"]


def test_rerun_skips_every_finished_run(swept, capsys):
    tmp, argv, _ = swept
    assert main(argv) == 0
    assert "16 runs: 16 already in" in capsys.readouterr().out


def test_report_reads_sweep_run_folders(swept):
    tmp, _, rows = swept
    folders = [r["run_dir"] for r in rows[:2]]
    argv = ["report", *folders, str(tmp / "runs.db"), "--out", str(tmp / "report"), "--quiet"]
    assert main(argv) == 0
    md = (tmp / "report" / "report.md").read_text()
    assert "## Run 2:" in md and "16 run(s), 0 failed." in md
    overrides = rows[0]["params"]
    assert (
        f"| architecture overrides (sweep) | pipelines = {overrides['pipelines']}, "
        f"formats.interp.weight_bits = {overrides['formats.interp.weight_bits']} |" in md
    )
    assert "the published figures are for the machine as built" in md
    sweep_rows = [line for line in md.splitlines() if line.startswith("| phantom=")]
    assert len(sweep_rows) == 16


def test_failed_runs_are_recorded_and_do_not_stop_the_sweep(tmp_path, capsys):
    (tmp_path / "s.toml").write_text(
        '[sweep]\nscene = ["head-perspective"]\nphantom = ["ball:size=16"]\nimage = [16]\n'
        'arch = ["volumepro500", "volumepro1000"]\n'
    )
    db = tmp_path / "runs.db"
    assert main(["sweep", str(tmp_path / "s.toml"), "--workers", "1", "--db", str(db)]) == 1
    assert "1 run(s) failed" in capsys.readouterr().err
    with RunsDB(db) as runs:
        status = {r["params"]["arch"]: (r["status"], r["error"]) for r in runs.rows()}
    assert status["volumepro1000"] == ("ok", None)
    assert status["volumepro500"][0] == "error"
    assert "volumepro500 renders parallel projection only" in status["volumepro500"][1]


def test_sweep_on_an_existing_scheduler(tmp_path, capsys):
    from hwsim.studies.sweep import local_client

    (tmp_path / "s.toml").write_text('[sweep]\nphantom = ["ball:size=16"]\nimage = [16]\n')
    db = tmp_path / "runs.db"
    with local_client(1) as client:
        address = client.scheduler.address
        assert (
            main(["sweep", str(tmp_path / "s.toml"), "--scheduler", address, "--db", str(db)]) == 0
        )
    assert "1 runs: 0 already in" in capsys.readouterr().out
    with RunsDB(db) as runs:
        (row,) = runs.rows()
    assert row["status"] == "ok" and row["worker"].startswith("tcp://127.0.0.1:")


def test_an_unreachable_scheduler_is_bad_input(tmp_path, capsys):
    (tmp_path / "s.toml").write_text('[sweep]\nphantom = ["ball:size=16"]\n')
    argv = ["sweep", str(tmp_path / "s.toml"), "--db", str(tmp_path / "r.db")]
    assert main([*argv, "--scheduler", "tcp://127.0.0.1:9"]) == 2
    err = capsys.readouterr().err
    assert "--scheduler: cannot reach the scheduler at tcp://127.0.0.1:9" in err
    assert not (tmp_path / "r.db").exists()  # nothing written before the scheduler answered


def test_every_timed_row_holds_its_energy_and_area(tmp_path):
    """hwsim.energy in each cycle and transaction row, priced in the node the sweep names;
    one pipeline has a quarter of four's datapath area; functional rows have none."""
    (tmp_path / "s.toml").write_text(
        'schema = 1\n[sweep]\narch = ["volumepro500"]\n'
        'fidelity = ["cycle", "transaction", "functional"]\n'
        'phantom = ["head:size=16"]\nimage = [16]\npipelines = [1, 4]\n'
        'technology = ["cmos350", "cmos45"]\n'
    )
    db = tmp_path / "runs.db"
    argv = ["sweep", str(tmp_path / "s.toml"), "--workers", "1", "--db", str(db), "--quiet"]
    assert main(argv) == 0
    with RunsDB(db) as runs:
        rows = runs.rows()
    assert len(rows) == 12 and all(r["status"] == "ok" for r in rows)
    area = {}
    for r in rows:
        stats = r["stats"]
        if r["fidelity"] == "functional":
            assert r["energy_joules"] is None and stats["energy"] is None
            continue
        assert r["technology"] == stats["technology"]["name"] == r["params"]["technology"]
        assert r["energy_joules"] == stats["energy"]["total_joules"] > 0
        assert r["energy_per_sample_joules"] == stats["energy"]["per_sample_joules"] > 0
        assert r["area_mm2"] == stats["area"]["total_mm2"] > 0
        key = r["fidelity"], r["params"]["pipelines"], r["technology"]
        area[key] = stats["area"]["units"]["interp"]["mm2"]
    for rung in ("cycle", "transaction"):
        for tech in ("cmos350", "cmos45"):
            assert area[rung, 4, tech] == pytest.approx(4 * area[rung, 1, tech])
        assert area[rung, 4, "cmos45"] < area[rung, 4, "cmos350"] / 50


def test_an_unknown_technology_is_refused_when_the_sweep_is_read(tmp_path, capsys):
    (tmp_path / "s.toml").write_text('schema = 1\n[sweep]\ntechnology = ["cmos9"]\n')
    argv = ["sweep", str(tmp_path / "s.toml"), "--workers", "1", "--db", str(tmp_path / "r.db")]
    assert main([*argv, "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "s.toml" in err and "sweep.technology" in err and "cmos45" in err
    assert not (tmp_path / "r.db").exists()


def test_sweep_rows_are_sorted_and_the_compiling_run_is_marked(swept):
    """One worker process: its first run pays the JIT compile and says so; the report's
    sweep table lists the runs by their parameters, not in the order they finished."""
    tmp, _, rows = swept
    assert sorted(r["includes_compile"] for r in rows) == [0] * (len(rows) - 1) + [1]
    argv = ["report", str(tmp / "runs.db"), "--out", str(tmp / "report-sweep"), "--quiet"]
    assert main(argv) == 0
    md = (tmp / "report-sweep" / "report.md").read_text()
    lines = [line for line in md.splitlines() if line.startswith("| phantom=")]
    labels = [line.split(" | ")[0].strip("| ") for line in lines]
    by_label = {r["label"]: r["params"] for r in rows}
    keys = [tuple(sorted(by_label[label].items())) for label in labels]
    assert keys == sorted(keys)
    assert sum("| yes [1] |" in line for line in lines) == 1
    assert "[1] The first run of its worker process" in md
