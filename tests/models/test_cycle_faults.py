"""The cycle image comes from the modelled hardware: break a structure, the image changes.

Issue: a stuck memory module, a dropped ring hand-off or a FIFO one entry too shallow
changes the cycle image where predicted (or deadlocks with a clear report), while the
functional image, which has no such hardware, stays the same.  Also: elision of unused
units changes neither the image nor the cycle count.
"""

from __future__ import annotations

import numpy as np
import pytest
import rungs

from hwsim.engine import DeadlockError
from hwsim.golden import make_plan
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.scene import CropSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom
from models.cycle import render_cycle
from models.frame import frame_of
from models.machines.cube4.cycle import Faults

pytestmark = pytest.mark.model


scene_of = rungs.fault_scene


@pytest.fixture(scope="module")
def head():
    return make_phantom("head", size=24)


def run(scene, volume, **kw):
    return rungs.functional_and_cycle(scene, volume, "cube4", **kw)[:2]


@pytest.mark.parametrize(
    "faults",
    [
        Faults(stuck_module=(1, 4095)),
        Faults(dropped_link=2),
        Faults(dropped_handoff=0),
        Faults(beam_fifo_adjust=-1),
        Faults(slice_fifo_adjust=-1),
    ],
    ids=["stuck-module", "dropped-ring-link", "dropped-acc-handoff", "beam-fifo", "slice-fifo"],
)
def test_each_broken_structure_changes_the_cycle_image_not_the_functional(head, faults):
    scene = scene_of()
    clean_f, clean_c = run(scene, head)
    broken_f, broken_c = run(scene, head, faults=faults)
    assert np.array_equal(clean_c.image, clean_f.image)
    assert np.array_equal(broken_f.image, clean_f.image)  # functional has no such hardware
    assert not np.array_equal(broken_c.image, clean_c.image)
    assert broken_c.cycles == clean_c.cycles  # data faults, not timing faults


def test_a_stuck_module_touches_only_samples_that_read_it(head):
    """MIP of a module stuck at full scale: every ray through the volume sees one of its
    voxels, so every touched pixel rises to the maximum value -- and nothing else."""
    scene = scene_of(mode="mip")
    _, clean = run(scene, head)
    _, stuck = run(scene, head, faults=Faults(stuck_module=(0, 4095)))
    lo, hi = head.value_range
    touched = clean.image > lo
    assert np.all(stuck.image[touched] >= clean.image[touched])
    assert np.all(stuck.image[~touched] == clean.image[~touched])
    assert (stuck.image[touched] > clean.image[touched]).mean() > 0.5


def test_a_short_slice_fifo_is_harmless_where_no_z_neighbour_is_used(head):
    """Predicted: slice FIFOs feed only the z-differences of gradients; an unlit scene
    without gradient modulation does not elaborate them, so the fault cannot show."""
    scene = scene_of(lighting=False)
    f, c = run(scene, head, faults=Faults(slice_fifo_adjust=-1))
    assert "gradient" in c.elided_units
    assert np.array_equal(c.image, f.image)


def test_a_pixel_fifo_that_can_never_accept_deadlocks_with_a_report(head):
    with pytest.raises(DeadlockError, match=r"pixel_bus\.fifo: depth 0 .* cycle \d+"):
        run(scene_of(), head, faults=Faults(pixel_fifo_depth=0))


@pytest.mark.parametrize(
    ("scene", "elided"),
    [
        (scene_of(mode="mip"), {"gradient", "classify", "shade", "crop"}),
        (scene_of(mode="xray"), {"gradient", "classify", "shade", "crop"}),
        (scene_of(lighting=False), {"gradient", "shade", "crop"}),
        (scene_of(), {"crop"}),
        (scene_of(crop=CropSpec(x=(2.0, 20.0))), set()),
    ],
    ids=["mip", "xray", "unlit", "lit", "cropped"],
)
def test_elided_model_equals_the_full_model_in_image_and_cycles(head, scene, elided):
    f, lean = run(scene, head)
    _, full = run(scene, head, elaborate_all=True)
    assert set(lean.elided_units) == elided and full.elided_units == []
    assert np.array_equal(lean.image, full.image) and np.array_equal(lean.image, f.image)
    assert lean.cycles == full.cycles
    for unit in elided:
        assert f"pipeline[0].{unit}.busy_cycles" not in lean.counters
        assert f"pipeline[0].{unit}.busy_cycles" in full.counters


def test_buffer_capacities_come_from_the_arch_file_and_are_checked(head, tmp_path):
    import dataclasses

    from hwsim.core.errors import InputError

    arch = dataclasses.replace(
        resolve_arch("cube4"), buffers={"beam_fifo_entries": 7, "pixel_fifo_entries": 600}
    )
    scene = scene_of()
    tf = resolve_transfer(scene.transfer, head)
    plan = make_plan(scene, head, arch.order)
    small = dataclasses.replace(arch, buffers={**arch.buffers, "slice_fifo_entries": 10})
    narrow = dataclasses.replace(arch, buffers={"beam_fifo_entries": 6})
    with pytest.raises(InputError, match=r"buffers\.beam_fifo_entries.*>= 7"):
        render_cycle(frame_of(scene, head, tf, narrow, plan))
    with pytest.raises(InputError, match=r"buffers\.slice_fifo_entries.*>= 144"):
        render_cycle(frame_of(scene, head, tf, small, plan))
    typo = dataclasses.replace(arch, buffers={"beam_fifo": 3})
    with pytest.raises(InputError, match=r"buffers\.beam_fifo: unknown key"):
        render_cycle(frame_of(scene, head, tf, typo, plan))
    tight = dataclasses.replace(arch, buffers={**arch.buffers, "pixel_fifo_entries": 4})
    roomy = render_cycle(frame_of(scene, head, tf, arch, plan))
    slow = render_cycle(frame_of(scene, head, tf, tight, plan))
    assert np.array_equal(slow.image, roomy.image) and slow.cycles > roomy.cycles
    assert slow.counters["pixel_bus.fifo_depth"] == 4
    assert roomy.counters["pixel_bus.fifo_depth"] == 600
