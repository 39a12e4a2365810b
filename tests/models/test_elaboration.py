"""Every rung reports the same datapath units for a scene: one rule
(:func:`models.datapath.units_needed`) decides what a scene elaborates and elides.

The cycle rungs add their machine's structures (memory, ring or cache, pixel bus) around
the datapath units; the datapath units themselves must be the other rungs'.  (Iso
surfaces once elaborated the classifier on the cycle rung only, though no rung uses it.)
"""

from __future__ import annotations

import pytest
from rungs import scene_of

from hwsim.run.fidelity import render
from hwsim.spec.scene import TransferSpec
from hwsim.volumes import make_phantom
from models.datapath import DATAPATH_UNITS

pytestmark = pytest.mark.model

MODULATED = TransferSpec(preset="ct", gradient_opacity=((0.0, 0.2), (200.0, 1.0)))


@pytest.fixture(scope="module")
def head():
    return make_phantom("head", size=12)


@pytest.mark.parametrize("arch", ["cube4", "volumepro500", "vizard2"])
@pytest.mark.parametrize(
    ("mode", "lit", "transfer"),
    [
        ("composite", True, None),
        ("composite", False, None),
        ("composite", False, MODULATED),
        ("iso", True, None),
        ("iso", False, None),
        ("mip", False, None),
        ("xray", False, None),
    ],
)
def test_every_rung_elaborates_the_same_datapath_units(head, arch, mode, lit, transfer):
    extra = {} if transfer is None else {"transfer": transfer}
    scene = scene_of(30, 20, size=12, mode=mode, render={"lighting": lit}, **extra)
    reports = {}
    for rung in ("golden", "functional", "transaction", "cycle"):
        run = render(scene, fidelity=rung, arch=arch, volume=head, extend=True)
        datapath = [u for u in run.elaborated_units if u in DATAPATH_UNITS]
        reports[rung] = (datapath, sorted(run.elided_units))
    assert len(set(map(repr, reports.values()))) == 1, reports
    used, _ = reports["cycle"]
    assert ("classify" in used) == (mode == "composite")
    assert ("gradient" in used) == (lit or transfer is not None)
