"""The VolumePro 500's slice-FIFO timing (models/machines/volumepro/fifo_timing.py), the
candidate for the cycle rung's rules 3, 5 and 8 that the vg500 RTL top agrees with
(tests/rtl/test_vg500_top.py, tests/cosim/test_vg500_rung.py compare the two).  Here: its
mechanisms move its count the way they should, and what it does not model is refused."""

import dataclasses

import pytest

import hwsim
from hwsim.core.errors import InputError
from hwsim.studies.rtl_diff import _frame
from models.backend import Backend
from models.machines.volumepro.cycle import SlabFaults, SlabMachine
from models.machines.volumepro.fifo_timing import slice_fifo_timing, stream_latency


def machine(size=16, arch="volumepro500", faults=None, **render):
    scene = hwsim.load_scene(None, volume=f"head:size={size}", view=(30, 20), image=size)
    scene = scene.replace(render=dataclasses.replace(scene.render, mode="mip", **render))
    return SlabMachine(Backend(_frame(scene, arch, None)), faults=faults)


def test_the_pipelines_wait_for_the_first_voxel_only_then_stream():
    m = machine()
    t = slice_fifo_timing(m)
    n_a, n_kp, C = m.n_a, m.n_kp, m.C
    beams = (n_kp + 1) * n_a  # the priming period and one period per sample slice
    assert t.beam_begins.size == beams
    assert (t.beam_begins[1:] - t.beam_begins[:-1] >= C).all()
    assert t.beam_begins[-1] - C * (beams - 1) == t.stall_cycles  # every wait is a beam's
    # The first beam waits for its mini-block beam only: a burst's latency, far less than
    # the window of two slabs the cycle rung's rule 3 waits for.
    assert 0 < t.beam_begins[0] < 4 * C * m.n_a
    assert t.cycles >= beams * C + t.stall_cycles + stream_latency(C)


def test_a_smaller_slab_buffer_holds_the_pipelines_longer():
    base = slice_fifo_timing(machine())
    m = machine()
    least = 4 * m.C * (-(-m.n_a // 2) + 1)  # one slab of mini-block beams and one more
    adjust = least - m.capacity["slab_buffer_entries"]
    small = slice_fifo_timing(machine(faults=SlabFaults(slab_buffer_adjust=adjust)))
    assert small.stall_cycles > base.stall_cycles
    assert small.cycles - base.cycles == small.stall_cycles - base.stall_cycles


def test_what_it_does_not_model_is_refused_naming_the_key():
    with pytest.raises(InputError, match="supersampling"):
        slice_fifo_timing(machine(supersampling=2))
    with pytest.raises(InputError, match="pixel_fifo_entries"):
        slice_fifo_timing(machine(faults=SlabFaults(pixel_fifo_depth=1)))
