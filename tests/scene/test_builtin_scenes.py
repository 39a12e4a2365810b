"""Built-in scenes show what they are for at their defaults (a user's first render)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hwsim.run.fidelity import render
from hwsim.run.output import image_to_rgb8
from hwsim.spec.scene import builtin_scenes, load_scene

pytestmark = pytest.mark.system

LIT = 0.3  # luminance of a lit surface or a visible structure, on [0, 1]


def _luminance(image: np.ndarray) -> np.ndarray:
    """As image.png shows it (scalar modes are windowed to their range there)."""
    return image_to_rgb8(image)[0][..., :3].mean(axis=-1) / 255.0


@pytest.mark.parametrize("name", sorted(builtin_scenes()))
def test_every_builtin_scene_shows_a_lit_object_at_its_default_view(name):
    scene = load_scene(name)
    scene = scene.replace(view=dataclasses.replace(scene.view, width=64, height=64))
    lum = _luminance(render(scene, fidelity="golden").image)
    assert (lum > LIT).mean() > 0.05, f"{name}: only {(lum > LIT).mean():.1%} of the image is lit"


def test_marschner_lobb_shows_its_rings_at_its_defaults():
    """Rows through the middle cross several bright rings (the old view, at the clipped face
    z = -1, crossed none: the whole image stayed below LIT)."""
    image = render(load_scene("marschner-lobb"), fidelity="golden").image
    lum = _luminance(image)
    rows = lum[lum.shape[0] * 2 // 5 : lum.shape[0] * 3 // 5 : 8] > LIT
    bands = (rows[:, 1:] & ~rows[:, :-1]).sum(axis=1)
    assert bands.min() >= 4, f"bright bands per row: {bands.tolist()}"
