"""The VolumePro family's SDRAM image (:class:`models.machines.volumepro.memory.SdramVolume`):
the host's plane-by-plane write against every voxel's address computed at once."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hwsim.engine import Counters
from hwsim.memory import parse_memory
from hwsim.run.fidelity import render, resolve_arch
from models.machines.volumepro.memory import SdramVolume, layout


def _reference(raw: np.ndarray, memory, n: int) -> np.ndarray:
    z, y, x = np.indices(raw.shape)
    m, b, a = layout(memory, n, x, y, z)
    words = np.zeros((memory.modules, memory.sdram.banks, int(a.max()) + 1), np.uint16)
    words[m, b, a] = raw
    return words


@pytest.mark.parametrize("skew", ["miniblock", "block"])
@pytest.mark.parametrize("shape", [(8, 8, 8), (7, 10, 5), (13, 6, 9), (1, 4, 4)])
def test_the_words_are_every_voxel_at_its_address_and_no_more(skew, shape) -> None:
    """Sized up front from the last planes (the mini-block layout's top) or grown and cut
    (the block layout's banks wrap): the same words, and the array ends at the highest
    address written."""
    arch = resolve_arch("volumepro1000")
    memory = dataclasses.replace(parse_memory(arch.memory, source=arch.source), skew=skew)
    raw = np.random.default_rng(3).integers(0, 1 << 12, size=shape).astype(np.uint16)
    sdram = SdramVolume(raw, memory, arch.pipelines, Counters())
    expected = _reference(raw, memory, sdram.n)
    assert sdram.words.shape == expected.shape
    assert sdram.words.flags.c_contiguous
    np.testing.assert_array_equal(sdram.words, expected)


def test_a_frame_whose_words_are_not_kept_renders_as_one_whose_are(monkeypatch) -> None:
    """Past ``KEEP_WORDS`` (a 512^3 volume) the words are written again for each frame and
    dropped after the data pass: two frames of one volume give the kept run's image,
    cycles and counters, and nothing stays with the volume."""
    from hwsim.spec.scene import Scene, TransferSpec, ViewSpec
    from hwsim.volumes import make_phantom
    from models.machines.volumepro import memory as vp_memory

    def frames(volume):
        scene = Scene(
            transfer=TransferSpec(preset="ct"), view=ViewSpec(azimuth=30, width=12, height=12)
        )
        runs = [render(scene, fidelity="cycle", arch="volumepro1000", volume=volume)]
        runs.append(render(scene, fidelity="cycle", arch="volumepro1000", volume=volume))
        return [(r.image.tobytes(), r.cycles, sorted(r.counters.items())) for r in runs]

    kept_volume = make_phantom("head", size=13)
    kept = frames(kept_volume)
    assert vp_memory._WORDS[kept_volume]
    monkeypatch.setattr(vp_memory, "KEEP_WORDS", 0)
    volume = make_phantom("head", size=13)
    assert frames(volume) == kept
    assert not vp_memory._WORDS.get(volume)


def _frame(arch: str, size: int = 13):
    from hwsim.spec.scene import Scene, TransferSpec, ViewSpec
    from hwsim.volumes import make_phantom

    view = ViewSpec(azimuth=30, width=12, height=12)
    scene = Scene(transfer=TransferSpec(preset="ct"), view=view)
    run = render(scene, fidelity="cycle", arch=arch, volume=make_phantom("head", size=size))
    return run.image.tobytes(), run.cycles, sorted(run.counters.items())


@pytest.mark.parametrize("arch", ["volumepro500", "volumepro1000"])
def test_a_frame_timed_with_narrow_cycles_is_timed_as_with_wide(arch, monkeypatch) -> None:
    """The compiled timing loop holds a large frame's per-request cycles as int32: forced
    on a small frame, the same image, cycles and counters as int64."""
    from models.machines.volumepro import timing_kernel

    wide = _frame(arch)
    monkeypatch.setattr(timing_kernel, "NARROW_FROM", -1)
    assert _frame(arch) == wide


def test_cycles_that_left_int32_are_told() -> None:
    """A wrapped READ cycle (negative, or not increasing) sends the frame round again wide."""
    from types import SimpleNamespace

    from models.machines.volumepro.timing_kernel import _wrapped

    def ctl(reads):
        out = np.zeros((4, len(reads)), np.int32)
        out[0] = reads
        return SimpleNamespace(_out=out, _n=len(reads))

    assert not _wrapped([ctl([3, 7, 11]), ctl([])])
    assert _wrapped([ctl([3, 7, 11]), ctl([5, -2147483000])])
    assert _wrapped([ctl([-5, 4])])
    assert _wrapped([ctl([9, 9])])
    assert _wrapped([ctl([2147483640, -2147483646])])  # int32 steps would read +10
