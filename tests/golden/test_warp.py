"""The shear-warp's 2-D warp filter, compiled, is the array expression it replaced, bit
for bit (the golden and fixed-point rungs both warp through it)."""

from __future__ import annotations

import numpy as np
import pytest

from hwsim.golden.steps import bilinear_2d

pytestmark = pytest.mark.golden


def _array_expression(image, a, b, background):
    rows, cols = image.shape[:2]
    pad = np.full((rows + 2, cols + 2) + image.shape[2:], background, dtype=np.float64)
    pad[1:-1, 1:-1] = image
    a = np.clip(a + 1.0, 0.0, rows + 1.0)
    b = np.clip(b + 1.0, 0.0, cols + 1.0)
    a0 = np.minimum(np.floor(a).astype(np.int64), rows)
    b0 = np.minimum(np.floor(b).astype(np.int64), cols)
    fa, fb = a - a0, b - b0
    if image.ndim == 3:
        fa, fb = fa[:, None], fb[:, None]
    near = (1 - fb) * pad[a0, b0] + fb * pad[a0, b0 + 1]
    far = (1 - fb) * pad[a0 + 1, b0] + fb * pad[a0 + 1, b0 + 1]
    return (1 - fa) * near + fa * far


@pytest.mark.parametrize("shape", [(37, 41, 4), (20, 30), (5, 7, 3), (1, 1, 4)])
@pytest.mark.parametrize("background", [0.0, 0.3, -1024.0])
def test_the_compiled_warp_is_the_array_expression(rng, shape, background):
    image = rng.random(shape) * 3000 - 1000
    a = rng.uniform(-3, shape[0] + 3, 20000)
    b = rng.uniform(-3, shape[1] + 3, 20000)
    a[:50], b[:50] = np.floor(a[:50]), np.floor(b[:50]) + 0.5  # on pixel centres, halves
    got, want = bilinear_2d(image, a, b, background), _array_expression(image, a, b, background)
    assert got.shape == want.shape and np.array_equal(got, want)
