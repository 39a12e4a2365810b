"""The VolumePro-family transaction model's chunk bursts (``chunk_reads.chunk_streams``):
the compiled split over the kept slab layouts gives, module by module and chunk by chunk,
the bursts of laying out every read mini-block with the shared mini-block layout
(``lanes.miniblock_layout``, ``memory.mini_block_bursts``) in read order."""

from __future__ import annotations

import numpy as np
import pytest
import rungs

from hwsim.run.fidelity import resolve_arch
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom
from models.frame import frame_of
from models.machines.volumepro import chunk_reads
from models.machines.volumepro.lanes import miniblock_layout
from models.machines.volumepro.memory import mini_block_bursts
from models.transaction import termination_pass, transaction_model

pytestmark = pytest.mark.model


def model_of(arch_name: str, az: float, el: float, size: int = 24):
    volume = make_phantom("head", size=size)
    scene = rungs.scene_of(
        az, el, phantom="head", size=32, preset="auto", render={"early_termination": 0.9}
    )
    tf = resolve_transfer(scene.transfer, volume)
    model = transaction_model(frame_of(scene, volume, tf, resolve_arch(arch_name)))
    model.ends = termination_pass
    model.run()
    chunks, _, _ = model._schedule(model.plan.n_steps)
    return model, chunks


def reference(model, chunks):
    """Per module, every read burst's (bank, row, chunk) in read order: each read
    mini-block laid out on its own."""
    out = [[] for _ in range(model.memory.modules)]
    n_mb = -(-model.n_b // 2)
    for c, (_, slab, lo, hi) in enumerate(chunks):
        for u in range(lo, hi + 1):
            for m in range(n_mb):
                if model.skips is not None and not model.skips.needed[slab, u, m]:
                    continue
                voxel = [0, 0, 0]
                voxel[model.kp], voxel[model.a_ax], voxel[model.b_ax] = 2 * slab, 2 * u, 2 * m
                z, y, x = (np.array([v]) for v in voxel)
                mod, bank, address = miniblock_layout(model.memory, model.n_even, x, y, z)
                bursts = mini_block_bursts(model.memory, mod, bank, address, model.words_per_voxel)
                for k, b, r in zip(*(a.ravel().tolist() for a in bursts), strict=True):
                    out[k].append((b, r, c))
    return out


@pytest.mark.parametrize("arch_name", ["volumepro1000", "volumepro500"])
@pytest.mark.parametrize(("az", "el"), [(30, 20), (100, -35)])
def test_streams_are_the_read_mini_blocks_laid_out_in_read_order(arch_name, az, el):
    model, chunks = model_of(arch_name, az, el)
    chunk_reads._layouts.clear()
    fresh = chunk_reads.chunk_streams(model, chunks)
    kept = chunk_reads.chunk_streams(model, chunks)  # from the kept layout
    want = reference(model, chunks)
    assert sum(len(w) for w in want) > 0
    for streams in (fresh, kept):
        for k, (banks, rows, bounds, per) in enumerate(streams.modules):
            owner = np.repeat(np.arange(len(chunks)), per).tolist()
            got = list(zip(banks.tolist(), rows.tolist(), owner, strict=True))
            assert got == want[k]
            assert bounds == [0, *np.cumsum(per).tolist()]
        batches = [sum(1 for w in want if any(c == i for _, _, c in w)) for i in range(len(chunks))]
        assert streams.batches == batches
    if model.skips is not None:  # a mini-block not read drops its bursts (can fail)
        model.skips.needed[...] = False
        assert all(b.size == 0 for b, _, _, _ in chunk_reads.chunk_streams(model, chunks).modules)


def test_a_kept_layout_serves_only_its_own_axes():
    a, chunks_a = model_of("volumepro500", 30, 20)
    b, chunks_b = model_of("volumepro500", 100, 10)
    assert a.kp != b.kp
    chunk_reads._layouts.clear()
    first = chunk_reads.slab_layouts(a)
    assert chunk_reads.slab_layouts(a) is first
    other = chunk_reads.slab_layouts(b)
    assert other is not first and not all(
        np.array_equal(x, y) for x, y in zip(first, other, strict=True)
    )
