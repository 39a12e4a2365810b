"""The Cube-4 slice datapath is local: a band of a slice's beams, run through the ring and
beam FIFOs on its own (its stream the slice's stream over the band's clocks, its module
residue shifted by the band's first beam), delivers each corner of a cell exactly as the
whole slice does whenever the beams that corner comes from lie in the band -- and not
the first cell past that.

Each corner's reach, in beams past the cell's own: ``(a, b)`` through the beam FIFO 0
(``r`` for a FIFO shortened by ``adjust``: ``beam_fifo_reach``, 1 or 2); ``(a, b + 1)``
over the ring 0, but the far column's is its ``(a, b)`` (the edge replica), so ``r``
too; ``(a + 1, b)`` and ``(a + 1, b + 1)`` 1.  What a frame split across
workers by bands of beams relies on (issue 20; the halo's proof in
``models/machines/cube4/bands.py`` ``_band_origins`` uses these reaches).  A beam FIFO
made deeper than a beam reaches into the beam before the band, so that fault cannot be
split exactly."""

from __future__ import annotations

import numpy as np
import pytest

from hwsim.engine import Counters
from models.machines.common.slices import SliceDatapath, SlicePath, slice_schedule
from models.machines.cube4.bands import beam_fifo_reach

pytestmark = pytest.mark.model

#: Corner planes in ``SliceDatapath.corners`` order: ``(a, b)``, ``(a, b + 1)``,
#: ``(a + 1, b)``, ``(a + 1, b + 1)``.
CORNERS = ("v00", "v01", "v10", "v11")


def _stream(volume: np.ndarray, P: int, s: int) -> np.ndarray:
    sched = slice_schedule(volume.shape, P, 0, s)
    b = np.where(sched.valid, sched.b, 0)
    return np.where(sched.valid, volume[s][sched.a, b], 0)


def _exact_cells(P: int, n_a: int, n_b: int, fault: dict, rng) -> dict:
    """Per band ``(a_lo, a_hi)`` (beams ``a_lo .. a_hi - 1``) and corner, the band's cells
    (from ``a_lo``) whose corner equals the whole slice's on every slice and column."""
    volume = rng.integers(1, 4096, size=(3, n_a, n_b))
    bands = ((0, n_a // 2), (n_a // 4, 3 * n_a // 4), (n_a // 2, n_a))
    C = -(-n_b // P)
    exact: dict = {}
    for s in range(3):
        stream = _stream(volume, P, s)
        full = SliceDatapath(SlicePath(pipelines=P, **fault), (n_a, n_b), Counters())
        whole = full.corners(stream, s)
        for a_lo, a_hi in bands:
            part = SliceDatapath(SlicePath(pipelines=P, **fault), (a_hi - a_lo, n_b), Counters())
            band = part.corners(stream[:, a_lo * C : a_hi * C], s + a_lo)
            # Cell rows are stored from -2: band row r is cell a_lo + r - 2; compare cells
            # a_lo .. a_hi (the last one the band's own edge replica).
            same = (band[:, 2:] == whole[:, a_lo + 2 : a_hi + 3]).all(axis=2)
            for k, corner in enumerate(CORNERS):
                key = (a_lo, a_hi, corner)
                exact[key] = exact.get(key, True) & same[k]
    return exact


def _reaches(P: int, n_b: int, fault: dict) -> dict[str, int]:
    C = -(-n_b // P)
    r = beam_fifo_reach(C, fault.get("beam_fifo_adjust", 0))
    return {"v00": r, "v01": r, "v10": 1, "v11": 1}


def _check_reach(P: int, n_a: int, n_b: int, fault: dict, rng) -> None:
    """Every corner within its reach of the band's last beam is exact; in a band that
    ends before the slice does, the first cell past that is not."""
    reach = _reaches(P, n_b, fault)
    for (a_lo, a_hi, corner), same in _exact_cells(P, n_a, n_b, fault, rng).items():
        n_exact = a_hi - reach[corner] - a_lo  # cells a_lo .. a_hi - 1 - reach
        if a_hi == n_a:  # the slice's own end: its replicas and flush are the band's
            assert same.all(), (a_lo, a_hi, corner)
            continue
        assert same[:n_exact].all(), (a_lo, a_hi, corner)
        assert not same[n_exact], (a_lo, a_hi, corner, "reaches less far than claimed")


@pytest.mark.parametrize("P", [1, 3, 4, 5])
@pytest.mark.parametrize("shape", [(20, 17), (16, 16), (24, 9)])
def test_a_band_of_beams_delivers_the_slices_corners(P, shape):
    _check_reach(P, *shape, {}, np.random.default_rng(P))


@pytest.mark.parametrize(
    "fault", [{"dropped_link": 1}, {"beam_fifo_adjust": -1}], ids=["dropped-link", "short-fifo"]
)
def test_faults_inside_a_beam_stay_local(fault):
    _check_reach(4, 20, 17, fault, np.random.default_rng(7))


@pytest.mark.parametrize(
    ("P", "n_b", "adjust", "r"),
    [
        (4, 17, -1, 1),  # C = 5: the last group's corner reads the next beam's first
        (4, 17, -5, 1),  # -C: still the next beam
        (4, 17, -6, 2),  # -(C + 1), a FIFO of depth 0: the beam after next
        (3, 9, -4, 2),
        (32, 17, -1, 1),  # C = 1: every column is in the last group
        (32, 17, -2, 2),
    ],
)
def test_a_shortened_beam_fifo_reaches_r_beams_on(P, n_b, adjust, r):
    """``beam_fifo_reach`` is how far corner ``(a, b)`` reaches, no more and no less."""
    assert beam_fifo_reach(-(-n_b // P), adjust) == r
    _check_reach(P, 20, n_b, {"beam_fifo_adjust": adjust}, np.random.default_rng(11))


def test_a_beam_fifo_deeper_than_a_beam_reaches_outside_the_band():
    """Corner ``(a, b)`` of the band's first cell reads the beam before the band."""
    exact = _exact_cells(4, 20, 17, {"beam_fifo_adjust": 1}, np.random.default_rng(7))
    assert not exact[(5, 15, "v00")][0]
