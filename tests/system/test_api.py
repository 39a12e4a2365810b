"""The Python API (hwsim.api, docs/api.md): the doc's examples run, the issue's one-liner
runs on the run install, ``Run.save`` writes what ``hwsim render --out`` writes, bad input
is an InputError naming the key, and ``import hwsim`` stays light.

The doc's ``python`` blocks run in this process, in a scratch folder (their ``out/``
lands in ``tmp_path``), each as a script (``__name__ == "__main__"``); the one-liner runs
in a subprocess on the run install (``HWSIM_RUN_VENV``, the venv ``./dev run`` builds;
else this interpreter's venv), as test_readme.py does for the README.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest

import hwsim
from hwsim.cli.commands import main

REPO = Path(__file__).resolve().parents[2]
DOC = REPO / "docs" / "api.md"
pytestmark = pytest.mark.system

#: The issue's done-when command.
ONE_LINER = (
    "import hwsim; r = hwsim.render(hwsim.load_scene('head'), fidelity='functional', "
    "arch='volumepro500'); print(r.cycles)"
)
#: The public names, written out here so a change to the API is a change to this test too.
PUBLIC = set(
    "__version__ HwsimError InputError Run SweepResult arch archs load_scene load_volume "
    "render sweep trade".split()
)
#: Stats keys that measure this process, not the frame: they differ between two renders.
WALL = ("wall_seconds", "wall_samples_per_second")


def doc_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S)


def _python(env_name: str | None) -> Path:
    if env_name and os.environ.get(env_name):
        return Path(os.environ[env_name]) / "bin" / "python"
    return Path(sys.executable)


def test_the_doc_has_its_examples():
    blocks = doc_blocks()
    assert len(blocks) >= 4
    text = "\n".join(blocks)
    for call in ("hwsim.render(", "hwsim.arch(", "hwsim.sweep(", ".save(", "hwsim.InputError"):
        assert call in text, call


@pytest.mark.parametrize("index", range(len(doc_blocks())))
def test_each_doc_example_runs(index, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    code = compile(doc_blocks()[index], f"docs/api.md python block {index + 1}", "exec")
    exec(code, {"__name__": "__main__"})
    printed = capsys.readouterr().out
    assert printed.strip(), "every example prints what it shows"
    if "api-cube4" in doc_blocks()[index]:
        for name in ("image.png", "image.npy", "stats.json", "units.csv"):
            assert (tmp_path / "out" / "api-cube4" / name).stat().st_size > 0, name


def test_the_issue_one_liner_runs_on_the_run_install(tmp_path):
    python = _python("HWSIM_RUN_VENV")
    env = {**os.environ, "PYTHONWARNINGS": "ignore::DeprecationWarning"}
    done = subprocess.run(
        [str(python), "-c", ONE_LINER], cwd=tmp_path, env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr[-2000:]
    cycles = int(done.stdout.strip().splitlines()[-1])
    scene = hwsim.load_scene("head")
    assert cycles == hwsim.render(scene, fidelity="functional", arch="volumepro500").cycles
    assert not list(tmp_path.iterdir()), "render alone writes nothing"


def test_import_hwsim_stays_light():
    heavy = ("numpy", "numba", "amaranth", "dask", "distributed", "hwsim.api", "hwsim.run.fidelity")
    probe = f"import sys, hwsim; print([m for m in {heavy!r} if m in sys.modules])"
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


def test_all_lists_exactly_the_public_names():
    assert set(hwsim.__all__) == PUBLIC
    assert len(hwsim.__all__) == len(PUBLIC)
    for name in hwsim.__all__:
        assert getattr(hwsim, name) is not None, name
    names = {n for n in dir(hwsim) if not n.startswith("_")}
    modules = {n for n in names if isinstance(vars(hwsim).get(n), types.ModuleType)}
    assert names - modules <= PUBLIC  # besides the subpackages imported so far
    assert hwsim.InputError is __import__("hwsim.core.errors").core.errors.InputError


def test_the_api_names_are_functions_not_modules():
    """hwsim.arch, .sweep and .trade are the API's functions: the modules of those names
    live in their layers' packages (hwsim.spec.arch, hwsim.studies.sweep/.trade), and
    importing them leaves the functions in place."""
    import hwsim.spec.arch
    import hwsim.studies.sweep.spec
    import hwsim.studies.trade.ladder

    assert hwsim.arch("cube4", pipelines=8).pipelines == 8
    assert callable(hwsim.sweep) and callable(hwsim.trade)
    assert "SweepResult" in repr(__import__("inspect").signature(hwsim.sweep))


@pytest.mark.parametrize("fidelity", ["golden", "cycle"])
def test_save_writes_what_hwsim_render_out_writes(fidelity, tmp_path):
    flags = ["--phantom", "head:size=16", "--image", "16x12", "--view", "40,10"]
    flags += ["--fidelity", fidelity] + (["--arch", "cube4"] if fidelity == "cycle" else [])
    cli_dir, api_dir = tmp_path / "cli", tmp_path / "api"
    assert main(["render", *flags, "--out", str(cli_dir), "--quiet"]) == 0
    scene = hwsim.load_scene(None, phantom="head:size=16", image=(16, 12), view=(40, 10))
    arch = "cube4" if fidelity == "cycle" else None
    run = hwsim.render(scene, fidelity=fidelity, arch=arch)
    paths = run.save(api_dir)

    names = sorted(p.name for p in cli_dir.iterdir())
    assert (
        names == sorted(p.name for p in api_dir.iterdir()) == sorted(p.name for p in paths.values())
    )
    if fidelity == "cycle":
        assert {"throughput.csv", "units.csv", "memory.csv"} <= set(names)
    np.testing.assert_array_equal(np.load(cli_dir / "image.npy"), np.load(api_dir / "image.npy"))
    assert run.image is not None and np.array_equal(run.image, np.load(api_dir / "image.npy"))
    assert (cli_dir / "image.png").read_bytes() == (api_dir / "image.png").read_bytes()
    cli_stats = json.loads((cli_dir / "stats.json").read_text())
    api_stats = json.loads((api_dir / "stats.json").read_text())
    assert api_stats == run.stats  # Run.stats is what save writes
    for stats in (cli_stats, api_stats):
        for key in WALL:
            stats.pop(key)
        stats["counters"] = {k: v for k, v in stats["counters"].items() if "seconds" not in k}
    assert api_stats == cli_stats
    assert run.cycles == cli_stats["cycles"] and run.samples == cli_stats["samples"]
    for name in ("units.csv", "memory.csv"):
        if name in names:
            assert (cli_dir / name).read_text() == (api_dir / name).read_text(), name


def test_a_volume_file_and_its_phantom_spec(tmp_path):
    path = tmp_path / "ball.npy"
    ball = hwsim.load_volume("ball:size=16")
    np.save(path, ball.data)
    loaded = hwsim.load_volume(path, spacing=(2, 1, 1))
    assert np.array_equal(loaded.data, ball.data) and loaded.spacing == (2.0, 1.0, 1.0)
    scene = hwsim.load_scene("head", volume=str(path), mode="mip", image=8)
    assert scene.volume.path == str(path.resolve()) and scene.render.mode == "mip"
    assert hwsim.load_scene(scene, image=(8, 6)).view.height == 6
    assert hwsim.load_volume("head", size=8, noise=0).shape == (8, 8, 8)


@pytest.mark.parametrize(
    ("call", "key"),
    [
        (lambda: hwsim.load_scene("head", fidelity="cycle"), "fidelity"),
        (lambda: hwsim.load_scene("nope"), "scene"),
        (lambda: hwsim.load_scene("head", view=(400, 0)), "azimuth"),
        (lambda: hwsim.load_scene("head", view=(1,)), "view"),
        (lambda: hwsim.load_scene("head", image=(64, 0)), "image"),
        (lambda: hwsim.load_scene("head", mode="mips"), "mode"),
        (lambda: hwsim.load_scene("head", phantom="head:size=2"), "size"),
        (lambda: hwsim.load_scene("head", volume="head:size=8", phantom="ball"), "phantom"),
        (lambda: hwsim.load_volume("head", sizes=8), "sizes"),
        (lambda: hwsim.load_volume("ct.nrrd", shapes=(1, 1, 1)), "shapes"),
        (lambda: hwsim.render("head", fidelity="cycles"), "fidelity"),
        (lambda: hwsim.render("head", fidelity="cycle", arch="cube5"), "arch"),
        (lambda: hwsim.render("head", fidelity="cycle", samplng="ray"), "samplng"),
        (lambda: hwsim.render("head", volume="ct.nrrd"), "volume"),
        (lambda: hwsim.render("head", threads=0), "threads"),
        (lambda: hwsim.render("head", max_memory="lots"), "max_memory"),
        (lambda: hwsim.arch("cube4", pipelines=0), "pipelines"),
        (lambda: hwsim.arch("cube4", formats={"interp.weight_bits": 99}), "formats"),
        (lambda: hwsim.arch("cube4", lanes=2), "lanes"),
        (lambda: hwsim.sweep({"pipelines": [0]}, workers=1), "sweep.pipelines[0]"),
        (lambda: hwsim.sweep({"arch": ["cube4"]}, workers=0), "workers"),
        (lambda: hwsim.trade(image=4), "image"),
        (lambda: hwsim.trade(rungs="golden,gold", image=8, size=8), "rungs"),
        (lambda: hwsim.trade(widths=True, archs=["cube4", "em-cube"]), "archs"),
    ],
)
def test_bad_input_is_one_input_error_naming_the_key(call, key):
    with pytest.raises(hwsim.InputError) as info:
        call()
    text = str(info.value)
    assert "\n" not in text and key in text and "--" not in (info.value.key or ""), text


def test_a_run_timed_without_its_image_saves_stats_only(tmp_path):
    scene = hwsim.load_scene("head", phantom="head:size=16", image=16)
    run = hwsim.render(scene, fidelity="transaction", arch="cube4", timing_only=True)
    assert run.image is None and run.cycles and run.stats["image"] is None
    paths = run.save(tmp_path / "t")
    assert "png" not in paths and json.loads(paths["stats"].read_text())["cycles"] == run.cycles
