"""The slice-FIFO rules 3', 5', 8' (models/machines/volumepro/fifo_timing.py), the
VolumePro 500's and EM-Cube's cycle-rung rules since issue 35, which the vg500 RTL top
agrees with (tests/rtl/test_vg500_top.py, tests/cosim/test_vg500_rung.py compare the two).
Here: their mechanisms move the count the way they should, for what the first version
refused too (supersampling, sections, a pixel FIFO that fills), and which machines have
them."""

import dataclasses

import hwsim
import hwsim.run.fidelity
from hwsim.studies.rtl_diff import _frame
from models.backend import Backend
from models.machines.volumepro.cycle import SlabFaults, SlabMachine
from models.machines.volumepro.fifo_timing import (
    slice_fifo_timing,
    stream_latency,
    uses_slice_fifos,
)


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


def test_supersampling_reads_each_voxel_slice_once_in_the_period_that_first_needs_it():
    m = machine(supersampling=2)
    t = slice_fifo_timing(m)
    steps = m.plan.n_steps
    # The priming period, then one period per sample slice (two per voxel slice).
    assert t.beam_begins.size == (steps + 1) * m.n_a
    one = machine()
    slice_fifo_timing(one)
    assert m.counters.as_dict()["memory.bursts"] == one.counters.as_dict()["memory.bursts"]


def test_a_section_reads_its_rows_and_their_neighbours_a_beam_each():
    arch = dataclasses.replace(hwsim.run.fidelity.resolve_arch("volumepro500"), section_width=6)
    scene = hwsim.load_scene(None, volume="head:size=16", view=(30, 20), image=16)
    scene = scene.replace(render=dataclasses.replace(scene.render, mode="mip"))
    m = SlabMachine(Backend(_frame(scene, arch, None)))
    t = slice_fifo_timing(m)
    sections = m._sections()
    rows = sum(min(a1 + 1, m.n_a - 1) - max(a0 - 1, 0) + 1 for a0, a1 in sections)
    assert t.beam_begins.size == (m.n_kp + 1) * rows
    whole = slice_fifo_timing(machine())
    assert t.cycles > whole.cycles


def test_a_pixel_fifo_that_fills_freezes_the_pipelines():
    base = machine()
    free = slice_fifo_timing(base)
    m = machine(faults=SlabFaults(pixel_fifo_depth=2))
    frozen = slice_fifo_timing(m)
    c = m.counters.as_dict()
    assert c["pixel_bus.stall_cycles"] > 0 and c["pixel_bus.max_occupancy"] <= 2
    assert frozen.stall_cycles == free.stall_cycles  # the memory waits as before
    assert frozen.cycles > free.cycles


def test_which_machines_stream_through_slice_fifos():
    resolve = hwsim.run.fidelity.resolve_arch
    assert uses_slice_fifos(resolve("volumepro500")) and uses_slice_fifos(resolve("em-cube"))
    assert not uses_slice_fifos(resolve("volumepro1000"))  # rule 6 reads per window
    leaping = dataclasses.replace(resolve("volumepro500"), space_leaping=True)
    assert not uses_slice_fifos(leaping)
