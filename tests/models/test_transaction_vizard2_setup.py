"""VIZARD II's transaction set-up without the Backend: the kept occupancy is the
Backend's rule for every input it is keyed by, and ``mode``/``ert``/``need_grad`` are
the Backend's."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hwsim.golden import make_plan
from hwsim.golden.occupancy import occupancy_from_ranges
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.scene import Scene, TransferSpec, ViewSpec
from hwsim.spec.transfer import TransferFunction, resolve_transfer
from hwsim.volumes import make_phantom
from models.backend import Backend
from models.frame import frame_of
from models.machines.vizard2.config import BLOCK
from models.machines.vizard2.transaction import VizardTransaction, _leap_occupancy

pytestmark = pytest.mark.model


def _frame(volume, render=None, transfer=None, iso=None):
    arch = resolve_arch("vizard2")
    scene = Scene(transfer=TransferSpec(preset="ct"), view=ViewSpec(width=12, height=10))
    if render is not None or iso is not None:
        changes = {"mode": render or scene.render.mode, "iso_value": iso}
        scene = dataclasses.replace(scene, render=dataclasses.replace(scene.render, **changes))
    tf = transfer or resolve_transfer(scene.transfer, volume)
    return frame_of(scene, volume, tf, arch, make_plan(scene, volume, arch.order))


def _backend_rule(frame):
    occupied = Backend(frame).occupied_blocks(BLOCK)
    return None if occupied is None else occupancy_from_ranges(occupied, BLOCK).distance


@pytest.mark.parametrize("mode", ["composite", "iso", "mip"])
def test_the_kept_occupancy_follows_every_key(mode):
    volume = make_phantom("head", size=20)
    frames = [_frame(volume, mode)]
    base = frames[0].transfer
    rgba = base.rgba.copy()
    rgba[:, 3] = np.where(rgba[:, 3] > 0, 0.0, 0.5)  # another opacity, the same values
    frames.append(_frame(volume, mode, transfer=TransferFunction(values=base.values, rgba=rgba)))
    lo, hi = volume.value_range
    frames.append(_frame(volume, mode, iso=lo + 0.9 * (hi - lo)))
    frames.append(_frame(make_phantom("ball", size=20), mode))
    for _ in range(2):  # the second pass reads the kept ones
        for frame in frames:
            txn = VizardTransaction(frame)
            kept, rule = _leap_occupancy(txn), _backend_rule(frame)
            assert (kept is None) == (rule is None) == (mode == "mip")
            if rule is not None:
                assert np.array_equal(kept.distance, rule)
            be = Backend(frame)
            stops = be.ert < 1.0 if be.mode == "composite" else be.mode == "iso"
            assert txn.ert == (frame.arch.early_termination and stops)
    if mode == "composite":  # the opacities differ, so must the fields
        first, second = (_backend_rule(f) for f in frames[:2])
        assert not np.array_equal(first, second)
