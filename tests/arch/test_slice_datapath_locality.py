"""The Cube-4 slice datapath is local: a band of a slice's beams, run through the ring and
beam FIFOs on its own (its stream the slice's stream over the band's clocks, its module
residue shifted by the band's first beam), delivers every cell whose two beams lie in
the band exactly the corners the whole slice delivers.

What a frame split across workers by bands of beams relies on (issue 20): each part reads
and routes only its rows plus one beam of halo.  A beam FIFO made deeper than a beam
reaches into the beam before the band, so that fault cannot be split exactly."""

from __future__ import annotations

import numpy as np
import pytest

from hwsim.engine import Counters
from models.machines.common.slices import SliceDatapath, SlicePath, slice_schedule

pytestmark = pytest.mark.model


def _stream(volume: np.ndarray, P: int, s: int) -> np.ndarray:
    sched = slice_schedule(volume.shape, P, 0, s)
    b = np.where(sched.valid, sched.b, 0)
    return np.where(sched.valid, volume[s][sched.a, b], 0)


def _band_equals_slice(P: int, n_a: int, n_b: int, fault: dict, rng) -> bool:
    C = -(-n_b // P)
    volume = rng.integers(1, 4096, size=(3, n_a, n_b))
    for s in range(3):
        stream = _stream(volume, P, s)
        full = SliceDatapath(SlicePath(pipelines=P, **fault), (n_a, n_b), Counters())
        whole = full.corners(stream, s)
        for a_lo, a_hi in ((0, n_a // 2), (n_a // 4, 3 * n_a // 4), (n_a // 2, n_a)):
            part = SliceDatapath(SlicePath(pipelines=P, **fault), (a_hi - a_lo, n_b), Counters())
            band = part.corners(stream[:, a_lo * C : a_hi * C], s + a_lo)
            # Cell rows are stored from -2: band row r is the slice's row a_lo + r.
            inner = slice(2, 2 + (a_hi - a_lo) - 1)
            if not np.array_equal(band[:, inner], whole[:, a_lo + 2 : a_hi + 1]):
                return False
    return True


@pytest.mark.parametrize("P", [1, 3, 4, 5])
@pytest.mark.parametrize("shape", [(20, 17), (16, 16), (24, 9)])
def test_a_band_of_beams_delivers_the_slices_corners(P, shape):
    assert _band_equals_slice(P, *shape, {}, np.random.default_rng(P))


@pytest.mark.parametrize(
    "fault", [{"dropped_link": 1}, {"beam_fifo_adjust": -1}], ids=["dropped-link", "short-fifo"]
)
def test_faults_inside_a_beam_stay_local(fault):
    assert _band_equals_slice(4, 20, 17, fault, np.random.default_rng(7))


def test_a_beam_fifo_deeper_than_a_beam_reaches_outside_the_band():
    assert not _band_equals_slice(4, 20, 17, {"beam_fifo_adjust": 1}, np.random.default_rng(7))
