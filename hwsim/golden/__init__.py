"""The float64 NumPy golden renderer (design section 4) and the sample plans it shares.

Conventions are stated in ``docs/numerics.md`` and in each module's docstring.
"""

from hwsim.golden.camera import Camera, index_to_world, view_vectors, world_to_index
from hwsim.golden.occupancy import Occupancy
from hwsim.golden.positions import SAMPLINGS, SamplePlan, Step, make_plan
from hwsim.golden.render import GoldenResult, occupancy_for, render_golden
from hwsim.golden.sampling import (
    Taps,
    gradient_at_voxels,
    sample,
    taps,
    trilinear,
    trilinear_rows,
    voxel_gradients,
)

__all__ = [
    "SAMPLINGS",
    "Camera",
    "GoldenResult",
    "Occupancy",
    "SamplePlan",
    "Step",
    "Taps",
    "index_to_world",
    "gradient_at_voxels",
    "make_plan",
    "occupancy_for",
    "render_golden",
    "sample",
    "taps",
    "trilinear",
    "trilinear_rows",
    "view_vectors",
    "voxel_gradients",
    "world_to_index",
]
