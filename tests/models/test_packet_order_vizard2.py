"""VIZARD II's packet order (the ray generator's tiles, ``ray_queue_entries`` rays a
packet): the compiled counting sort gives the NumPy lexsort's order and cuts exactly."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from models.machines.vizard2.transaction import packet_order, packet_order_reference

pytestmark = pytest.mark.model


@st.composite
def _rays(draw):
    height, width = draw(st.integers(1, 40)), draw(st.integers(1, 40))
    th, tw = draw(st.integers(1, 12)), draw(st.integers(1, 12))
    depth = draw(st.integers(1, 70))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    ids = np.flatnonzero(rng.random(height * width) < draw(st.floats(0.0, 1.0)))
    kind = draw(st.sampled_from(["sorted", "shuffled", "reversed"]))
    if kind == "shuffled":
        ids = rng.permutation(ids)
    elif kind == "reversed":  # a back-to-front or reordered plan's rays
        ids = ids[::-1].copy()
    return ids.astype(np.int64), width, th, tw, depth


@settings(max_examples=300, deadline=None)
@given(_rays())
def test_compiled_packet_order_is_the_lexsort(case):
    ids, width, th, tw, depth = case
    order, cuts = packet_order(ids, width, th, tw, depth)
    ref_order, ref_cuts = packet_order_reference(ids, width, th, tw, depth)
    assert order.dtype == ref_order.dtype == np.int64 and cuts.dtype == np.int64
    assert np.array_equal(order, ref_order) and np.array_equal(cuts, ref_cuts)


def test_a_broken_order_is_caught():
    """The comparison above sees a packet cut in the wrong place."""
    ids = np.arange(64, dtype=np.int64)
    order, cuts = packet_order(ids, 8, 4, 4, 3)
    ref_order, ref_cuts = packet_order_reference(ids, 8, 4, 4, 3)
    assert np.array_equal(cuts, ref_cuts)
    assert not np.array_equal(packet_order(ids, 8, 4, 4, 4)[1], ref_cuts)
    assert not np.array_equal(packet_order(ids, 8, 4, 2, 3)[0], ref_order)
