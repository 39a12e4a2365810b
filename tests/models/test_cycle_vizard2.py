"""The ``cycle`` rung on VIZARD II: bit-identical images, cache and SDRAM timing, ERT and
space leaping as timing mechanisms, counters that add up.

Design section 3: functional and cycle images are bit-identical for the same scene and
machine; the VIZARD II cycle image is built from the voxels its block cache delivered
(test_cycle_vizard2_faults.py breaks the structures to prove it).
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
import rungs

from hwsim.core.errors import InputError
from hwsim.run.fidelity import render, resolve_arch
from hwsim.spec.scene import CropSpec, TransferSpec
from hwsim.volumes import make_phantom
from models.machines.vizard2.config import BLOCK, FEEDBACK
from models.machines.vizard2.cycle import UNITS
from models.units import interp as interp_unit

pytestmark = pytest.mark.model

MODES = ["composite", "mip", "minip", "xray", "iso"]


#: The VIZARD II tests look at a smaller image than the slice machines'.
scene_of = functools.partial(rungs.scene_of, size=20)


def vizard(**changes):
    """The built-in vizard2 with fields (and ``buffers`` keys) replaced."""
    return rungs.machine("vizard2", **changes)


def both(scene, volume, arch="vizard2", **kw):
    return rungs.functional_and_cycle(scene, volume, arch, **kw)


def assert_identical(fixed, cycle):
    """Bit-identical images and equal sample counts: the frame's planned samples on both
    rungs (what the machine issued, leaped and composited are counters)."""
    rungs.assert_identical(fixed, cycle)


@pytest.fixture(scope="module")
def head():
    return make_phantom("head", size=19)  # odd: edge blocks are partial


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize(("az", "el"), [(0, 0), (30, 20), (135, -40)])
def test_cycle_equals_functional_bit_for_bit_parallel(head, mode, az, el):
    fixed, cycle, _ = both(scene_of(az, el, mode=mode), head)
    assert_identical(fixed, cycle)
    if mode == "composite":
        assert cycle.image[..., 3].max() > 0.5  # not a trivially empty picture


@pytest.mark.parametrize("mode", ["composite", "mip", "xray", "iso"])
@pytest.mark.parametrize(("az", "el"), [(0, 0), (40, 25)])
def test_cycle_equals_functional_bit_for_bit_perspective(head, mode, az, el):
    scene = scene_of(az, el, mode=mode, projection="perspective")
    assert_identical(*both(scene, head)[:2])


#: :data:`rungs.FEATURE_VARIANTS` with Vizard II's crop and early termination, and
#: supersampling both ways.
FEATURE_VARIANTS = {
    **rungs.FEATURE_VARIANTS,
    "crop": {"crop": CropSpec(x=(3.0, 15.0), y=(2.0, 16.0), z=(0.0, 12.5))},
    "ert": {"render": {"early_termination": 0.8}},
    "ss2": {"render": {"supersampling": 2.0}},
    "ss0.5": {"render": {"supersampling": 0.5}},
}


@pytest.mark.parametrize("extra", list(FEATURE_VARIANTS.values()), ids=list(FEATURE_VARIANTS))
def test_scene_features_stay_bit_identical(head, extra):
    assert_identical(*both(scene_of(40, 15, **extra), head)[:2])


@pytest.mark.parametrize("pipelines", [1, 3, 8])
def test_any_pipeline_count_renders_the_same_image(head, pipelines):
    fixed, cycle, _ = both(scene_of(60, 25), head, vizard(pipelines=pipelines))
    assert_identical(fixed, cycle)


def test_marschner_lobb_and_ball():
    for name in ("marschner-lobb", "ball"):
        vol = make_phantom(name, size=18)
        for mode in ("composite", "mip"):
            tf = TransferSpec(preset="auto")
            assert_identical(*both(scene_of(25, 35, mode=mode, transfer=tf), vol)[:2])


def test_counters_add_up_and_throughput_never_exceeds_P(head):
    P = 3
    fixed, cycle, plan = both(scene_of(33, 21), head, vizard(pipelines=P))
    c = cycle.counters
    issued = c["frame.issued_samples"]
    assert 0 < issued <= P * cycle.cycles
    for unit in ["cache", *(u for u in cycle.elaborated_units if u in UNITS)]:
        inputs = 0
        for lane in range(P):
            parts = [c[f"pipeline[{lane}].{unit}.{k}_cycles"] for k in ("busy", "stall", "idle")]
            assert sum(parts) == cycle.cycles, (unit, lane, parts)
            inputs += c[f"pipeline[{lane}].{unit}.inputs"]
        assert inputs == issued
    assert c["cache.hits"] + c["cache.misses"] == c["cache.lookups"]
    assert c["cache.fills"] == c["cache.misses"] > 0
    # Every fill reads a block's values (64 x 16 bits: 16 words, 2 bursts of 8) and its
    # gradient-table entries (64 x 3 differences of 16 bits for <= 12-bit voxels, 24
    # bits for 16-bit voxels: 48 or 72 words, 6 or 9 bursts).
    bits = fixed_datapath(resolve_arch("vizard2"), head).voxel_bits
    per_fill = 2 + (6 if bits <= 12 else 9)
    assert c["memory.bursts"] == per_fill * c["cache.fills"]
    assert (
        c["memory.row_hits"] + c["memory.row_misses"] + c["memory.row_conflicts"]
        == (c["memory.bursts"])
    )
    # Rays that space leaping empties are never generated; the rest leave as pixels.
    assert c["pixel_bus.pixels"] == c["ray_generator.rays"] <= plan.ray_ids.size
    assert cycle.derived["samples_per_cycle"] <= P


def test_a_cache_that_holds_the_volume_misses_only_once_per_block():
    """16^3 voxels are 4^3 blocks: with 4 x 4 x 4 lines every block has its own line, so
    the misses are exactly the distinct blocks the samples touch (computed here from the
    sample positions, independently of the cache model)."""
    vol = make_phantom("head", size=16)
    scene = scene_of(30, 20, size=24, mode="mip")
    arch = vizard(buffers={"cache_sets": [4, 4, 4]})
    fixed, cycle, plan = both(scene, vol, arch)
    assert_identical(fixed, cycle)
    blocks = set()
    for step in plan.steps():
        idx = interp_unit.interp_taps(step.zyx, vol.shape, fixed_datapath(arch, vol).interp).idx
        z, rem = np.divmod(idx, 16 * 16)
        y, x = np.divmod(rem, 16)
        blocks.update(((z // BLOCK) * 16 + (y // BLOCK) * 4 + x // BLOCK).ravel().tolist())
    assert cycle.counters["cache.misses"] == len(blocks)
    # A 2 x 2 x 2 cache thrashes: more misses, more cycles, the same image.
    _, small, _ = both(scene, vol, vizard(buffers={"cache_sets": [2, 2, 2]}))
    assert np.array_equal(small.image, cycle.image)
    assert small.counters["cache.misses"] > len(blocks) and small.cycles > cycle.cycles


def fixed_datapath(arch, vol):
    from models.datapath import Datapath

    return Datapath.for_volume(arch, vol)


def test_issue_cycles_stalls_and_tail_make_the_frame(head):
    """Rules 1, 2, 5, 6 of docs/cycle.md: without ERT feedback the frame is the issue
    clocks (ceil(n / P) per round of n live rays of a packet), the stalls (cache fills,
    pixel FIFO), the pipeline latency and the final pixel drain -- nothing else.  The
    packets (4 x 4 tiles cut into queues of 6 rays) are replayed here from the plan."""
    P, R, tile = 2, 6, 4
    scene = scene_of(20, 10, mode="mip")
    arch = vizard(pipelines=P, buffers={"ray_queue_entries": R, "ray_tile": [tile, tile]})
    fixed, cycle, plan = both(scene, head, arch)
    assert_identical(fixed, cycle)
    width = plan.shape[1]
    rows, cols = plan.ray_ids // width, plan.ray_ids % width
    tiles = (rows // tile) * -(-width // tile) + cols // tile
    issue = 0
    for t in np.unique(tiles):
        mine = np.flatnonzero(tiles == t)  # ray ids ascend: row-major inside the tile
        for packet in (mine[i : i + R] for i in range(0, mine.size, R)):
            lo, hi = plan.j_lo[packet], plan.j_hi[packet]
            for j in range(lo.min(), hi.max() + 1):
                issue += -(-int(((lo <= j) & (j <= hi)).sum()) // P)
    c = cycle.counters
    stalls = c["pipeline[0].cache.stall_cycles"]
    assert stalls > 0  # fills cost real SDRAM time
    assert cycle.cycles == issue + stalls + FEEDBACK + c["pixel_bus.drain_cycles"]
    assert c["pipeline.latency_cycles"] == FEEDBACK


def test_early_termination_saves_cycles_not_pixels(head):
    scene = scene_of(30, 20, size=24, render={"early_termination": 0.9})
    fixed, with_ert, plan = both(scene, head)
    _, without, _ = both(scene, head, vizard(early_termination=False))
    assert_identical(fixed, with_ert)
    assert np.array_equal(without.image, with_ert.image)  # the compositor ignores dead rays
    c = with_ert.counters
    issued, speculative = c["frame.issued_samples"], c["ert.speculative_samples"]
    # Rule 3: a terminated ray's samples issued before the verdict came back are fetched
    # and discarded; every other issued sample is composited.
    assert issued == c["frame.composited_samples"] + speculative and speculative > 0
    assert issued < without.counters["frame.issued_samples"]
    assert with_ert.cycles < without.cycles
    assert "ert.speculative_samples" not in without.counters or (
        without.counters["ert.speculative_samples"] == 0
    )
    # The threshold effect, and only it: a ray stops once its opacity reaches 0.9, so it
    # misses at most 1 - 0.9 of opacity (plus one LSB of each output channel).
    _, full, _ = both(scene_of(30, 20, size=24), head)
    gap = np.abs(full.image[..., 3] - with_ert.image[..., 3])
    assert 0 < gap.max() <= 0.1 + 2.0**-11


def test_space_leaping_saves_cycles_not_pixels(head):
    scene = scene_of(30, 20, size=24)
    fixed, leaping, plan = both(scene, head)
    _, plain, _ = both(scene, head, vizard(space_leaping=False))
    assert_identical(fixed, leaping)
    assert np.array_equal(plain.image, leaping.image)
    assert leaping.counters["frame.leaped_samples"] > 0
    assert plain.counters["frame.issued_samples"] == plan.samples  # every planned sample
    assert plain.counters["ray_generator.rays"] == plan.ray_ids.size
    assert (
        leaping.counters["frame.issued_samples"]
        == plan.samples - leaping.counters["frame.leaped_samples"]
    )
    assert leaping.cycles < plain.cycles
    # MIP sees every sample: nothing to leap.
    mip = both(scene_of(30, 20, size=24, mode="mip"), head)[1]
    assert mip.counters["frame.leaped_samples"] == 0


def test_elision_changes_neither_image_nor_cycles(head):
    for scene in (scene_of(30, 20, mode="mip"), scene_of(30, 20, render={"lighting": False})):
        fixed, lean, _ = both(scene, head)
        _, full, _ = both(scene, head, elaborate_all=True)
        assert_identical(fixed, lean)
        assert np.array_equal(full.image, lean.image) and full.cycles == lean.cycles
        assert lean.elided_units and not full.elided_units
        assert "shade" in full.elaborated_units and "shade" not in lean.elaborated_units


def test_render_entry_point_and_refusals(head):
    run = render(scene_of(30, 20), fidelity="cycle", arch="vizard2", volume=head)
    assert run.cycles > 0 and run.clock_hz == 100e6
    assert "cache" in run.elaborated_units and "crop" in run.elided_units
    assert run.counters["cache.lookups"] > 0
    bad = [
        (vizard(buffers={"cache_sets": [1, 4, 4]}), "buffers.cache_sets"),
        (vizard(buffers={"ray_tiles": [8, 8]}), "buffers.ray_tiles"),
        (vizard(buffers={"ray_queue_entries": -1}), "buffers.ray_queue_entries"),
        (vizard(formats={}), "formats.gradient.source"),
        (vizard(memory={**resolve_arch("vizard2").memory, "rows": 1}), "memory.rows"),
        (vizard(memory={**resolve_arch("vizard2").memory, "modules": 2}), "memory.modules"),
        (vizard(memory={**resolve_arch("vizard2").memory, "skew": "cube4"}), "memory.skew"),
    ]
    for arch, key in bad:
        with pytest.raises(InputError, match=key.replace(".", r"\.")):
            both(scene_of(), head, arch)


def test_block_cache_matches_a_sequential_direct_mapped_cache(rng):
    """The vectorised lookups of one step against a plain loop: same hits and fills,
    and every corner delivers the voxel the volume holds (no faults)."""
    from models.machines.vizard2.config import memory_of
    from models.machines.vizard2.memory import BlockCache, VolumeImage

    raw = rng.integers(0, 4096, size=(11, 14, 9))
    image = VolumeImage(raw, memory_of(vizard()), voxel_bits=12, gradients=False)
    sets = (2, 3, 2)
    cache = BlockCache(sets, image)
    tags: dict[int, int] = {}
    hits = fills = 0
    nb = image.nb
    cfg = fixed_datapath(vizard(), make_phantom("ball", size=8)).interp
    for _ in range(6):
        zyx = rng.uniform(-0.5, np.array(raw.shape) - 0.5, size=(40, 3))
        idx = interp_unit.interp_taps(zyx, raw.shape, cfg).idx
        fetch = cache.fetch(idx)
        assert np.array_equal(fetch.corners(), raw.ravel()[idx])
        for i in range(idx.shape[1]):
            seen = []
            for c in range(8):
                z, rem = divmod(int(idx[c, i]), raw.shape[1] * raw.shape[2])
                y, x = divmod(rem, raw.shape[2])
                b = (z // 4, y // 4, x // 4)
                if b in seen:
                    continue
                seen.append(b)
                line = ((b[0] % sets[0]) * sets[1] + b[1] % sets[1]) * sets[2] + b[2] % sets[2]
                block = (b[0] * nb[1] + b[1]) * nb[2] + b[2]
                if tags.get(line) == block:
                    hits += 1
                else:
                    fills += 1
                    tags[line] = block
    assert (cache.hits, cache.fills) == (hits, fills) and hits > 0 and fills > 0
