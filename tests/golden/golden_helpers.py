"""Helpers for golden-renderer tests: scenes and volumes built in a line."""

from __future__ import annotations

import numpy as np

from hwsim.spec.scene import Light, RenderSpec, Scene, ViewSpec
from hwsim.spec.transfer import TransferFunction
from hwsim.volumes.volume import Volume


def make_scene(
    mode="composite",
    az=0.0,
    el=0.0,
    size=32,
    height=None,
    *,
    zoom=1.0,
    projection="parallel",
    lights=None,
    **render,
) -> Scene:
    view = ViewSpec(
        azimuth=az,
        elevation=el,
        width=size,
        height=height or size,
        zoom=zoom,
        projection=projection,
    )
    lights = (Light(),) if lights is None else lights
    return Scene(view=view, render=RenderSpec(mode=mode, **render), lights=lights)


def flat_tf(value_hi: float, alpha: float, rgb=(1.0, 0.5, 0.25)) -> TransferFunction:
    """Constant colour and opacity over [0, value_hi] (zero below 0)."""
    return TransferFunction(
        values=np.array([0.0, value_hi]), rgba=np.array([[*rgb, alpha], [*rgb, alpha]])
    )


def gaussian_volume(
    n: int = 40, sigma: float = 6.0, spacing=(1.0, 1.0, 1.0), peak: float = 1000.0
) -> Volume:
    """A Gaussian blob ``peak * exp(-|p|^2 / (2 sigma^2))`` in world units, centred."""
    shape = (n, n, n) if np.isscalar(n) else n
    axes = [(np.arange(k) - (k - 1) / 2) * s for k, s in zip(shape, spacing, strict=True)]
    z, y, x = np.meshgrid(*axes, indexing="ij")
    data = peak * np.exp(-(x**2 + y**2 + z**2) / (2 * sigma**2))
    return Volume(data=data, spacing=spacing)
