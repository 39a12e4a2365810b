"""Hold-out cases (issue 33), one class of bad input: a value of the wrong type (or out
of range) in each file kind: architecture, scene, technology, sweep, transfer file and
report inputs.  Listed in :data:`CASES`, in order."""

from __future__ import annotations

import numpy as np
from holdout_files import (
    CYCLE,
    RENDER,
    SWEEP,
    Case,
    _arch,
    _derived,
    _file,
    _run_dir,
    _scene,
    _tech,
    _valid_stats,
    registrar,
)

CASES: list[Case] = []
case = registrar(CASES)


# ------------------------------------------------------------------ wrong types


@case("arch: wrong type")
def arch_count_string(d):
    a = _arch(d, "count = 4 ", 'count = "four" ')
    return [*RENDER, *CYCLE[:2], "--arch", str(a)], [a]


@case("arch: wrong type")
def arch_clock_array(d):
    a = _arch(d, "clock_hz = 125e6", "clock_hz = [125e6]")
    return [*RENDER, *CYCLE[:2], "--arch", str(a)], [a]


@case("arch: wrong type")
def arch_voxel_bits_string(d):
    a = _arch(d, "voxel_bits = [8, 12, 16]", 'voxel_bits = "8"')
    return [*RENDER, "--fidelity", "functional", "--arch", str(a)], [a]


@case("arch: wrong type")
def arch_modes_string(d):
    a = _arch(d, 'modes = ["composite", "mip"]', 'modes = "composite"')
    return [*RENDER, "--fidelity", "functional", "--arch", str(a)], [a]


@case("arch: wrong type")
def arch_feature_switch_string(d):
    a = _arch(d, "perspective = true", 'perspective = "yes"')
    return [*RENDER, "--fidelity", "functional", "--arch", str(a)], [a]


@case("arch: wrong type")
def arch_negative_max_volume(d):
    a = _arch(d, "max_volume = [1024, 1024, 1024]", "max_volume = [1024, -1, 1024]")
    return [*RENDER, "--fidelity", "functional", "--arch", str(a)], [a]


@case("arch: wrong type")
def arch_name_number(d):
    a = _arch(d, 'name = "cube4"', "name = 4")
    return ["figures", "--arch", str(a), "--out", "fig", "--quiet"], [a]


@case("arch: wrong type")
def arch_technology_array(d):
    a = _arch(d, 'technology = "cmos350"', 'technology = ["cmos350"]')
    return [*RENDER, *CYCLE[:2], "--arch", str(a)], [a]


@case("scene: wrong type")
def scene_width_string(d):
    s = _scene(d, "width = 8", 'width = "8"')
    return ["render", str(s), "--quiet", "--out", "out"], [s]


@case("scene: wrong type")
def scene_light_direction_string(d):
    s = _scene(d, extra='[[lights]]\ndirection = "up"\n')
    return ["render", str(s), "--quiet", "--out", "out"], [s]


@case("scene: wrong type")
def scene_mode_number(d):
    s = _scene(d, extra="[render]\nmode = 3\n")
    return ["render", str(s), "--quiet", "--out", "out"], [s]


@case("scene: wrong type")
def scene_params_string(d):
    s = _scene(d, "params = { size = 8 }", 'params = "size=8"')
    return ["render", str(s), "--quiet", "--out", "out"], [s]


@case("scene: wrong type")
def scene_material_inf(d):
    s = _scene(d, extra="[material]\nambient = inf\n")
    return ["render", str(s), "--quiet", "--out", "out"], [s]


@case("scene: wrong type")
def scene_crop_string(d):
    s = _scene(d, extra='[crop]\nmin = "a"\n')
    return ["render", str(s), "--quiet", "--out", "out"], [s]


@case("scene: wrong type")
def scene_cut_planes_number(d):
    s = _scene(d, "schema = 1\n", "schema = 1\ncut_planes = 5\n")
    return ["render", str(s), "--quiet", "--out", "out"], [s]


@case("scene: wrong type")
def scene_view_azimuth_array(d):
    s = _scene(d, "width = 8", "width = 8\nazimuth = [1, 2]")
    return ["render", str(s), "--quiet", "--out", "out"], [s]


@case("technology: wrong type")
def tech_node_string(d):
    t = _tech(d, "node_nm = 45", 'node_nm = "45"')
    return [*RENDER, *CYCLE, "--technology", str(t)], [t]


@case("technology: wrong type")
def tech_vdd_zero(d):
    t = _tech(d, "vdd = 0.9", "vdd = 0")
    return [*RENDER, *CYCLE, "--technology", str(t)], [t]


@case("technology: wrong type")
def tech_energy_value_string(d):
    t = _tech(d, "value = 0.1,", 'value = "0.1",')
    return [*RENDER, *CYCLE, "--technology", str(t)], [t]


@case("technology: wrong type")
def tech_base_number(d):
    t = _tech(d, 'name = "cmos45"', 'name = "cmos45"\nbase = 7')
    return [*RENDER, *CYCLE, "--technology", str(t)], [t]


@case("technology: wrong type")
def tech_base_missing_file(d):
    t = _derived(d, "nowhere.toml")
    return [*RENDER, *CYCLE, "--technology", str(t)], [t]


@case("sweep: wrong type")
def sweep_phantom_number(d):
    w = _file(d, "w.toml", SWEEP.replace('phantom = ["ball:size=8"]', "phantom = 5"))
    return ["sweep", str(w), "--db", "runs.db", "--quiet"], [w]


@case("sweep: wrong type")
def sweep_image_string(d):
    w = _file(d, "w.toml", SWEEP.replace("image = [8]", 'image = ["big"]'))
    return ["sweep", str(w), "--db", "runs.db", "--quiet"], [w]


@case("sweep: wrong type")
def sweep_no_sweep_table(d):
    w = _file(d, "w.toml", "schema = 1\n")
    return ["sweep", str(w), "--db", "runs.db", "--quiet"], [w]


@case("sweep: wrong type")
def sweep_unknown_fidelity(d):
    w = _file(d, "w.toml", SWEEP.replace('["golden"]', '["warp"]'))
    return ["sweep", str(w), "--db", "runs.db", "--quiet"], [w]


@case("sweep: wrong type")
def sweep_zero_pipelines(d):
    w = _file(d, "w.toml", SWEEP + 'arch = ["cube4"]\npipelines = [0]\n')
    return ["sweep", str(w), "--db", "runs.db", "--quiet"], [w]


@case("transfer: wrong type")
def transfer_preset_number(d):
    t = _file(d, "tf.toml", "schema = 1\npreset = 7\n")
    return [*RENDER, "--transfer", str(t)], [t]


@case("transfer: wrong type")
def transfer_table_number(d):
    t = _file(d, "tf.toml", "schema = 1\ntable = 5\n")
    return [*RENDER, "--transfer", str(t)], [t]


@case("report: wrong type")
def report_stats_null(d):
    run = _run_dir(d, "null", np.zeros((8, 8)))
    return ["report", str(run), "--out", "rep", "--quiet"], [run / "stats.json"]


@case("report: wrong type")
def report_stats_fidelity_number(d):
    stats = _valid_stats().replace('"fidelity": "golden"', '"fidelity": 5')
    assert '"fidelity": 5' in stats
    run = _run_dir(d, stats, np.zeros((8, 8)))
    return ["report", str(run), "--out", "rep", "--quiet"], [run / "stats.json"]


@case("report: wrong type")
def report_image_4d(d):
    run = _run_dir(d, image=np.zeros((2, 2, 2, 2)))
    return ["report", str(run), "--out", "rep", "--quiet"], [run / "image.npy"]


@case("report: wrong type")
def report_image_complex(d):
    run = _run_dir(d, image=np.zeros((8, 8), dtype=complex))
    return ["report", str(run), "--out", "rep", "--quiet"], [run / "image.npy"]


@case("report: wrong type")
def report_trade_rows_string(d):
    t = _file(d / "trade", "trade.json", '{"schema": 1, "rows": "x"}')
    return ["report", str(t.parent), "--out", "rep", "--quiet"], [t]


@case("report: wrong type")
def report_figures_list(d):
    f = _file(d / "fig", "figures.json", "[]")
    return ["report", str(f.parent), "--out", "rep", "--quiet"], [f]
