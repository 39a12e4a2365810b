"""Fixed-point formats (rounding, saturation) and error metrics.  See docs/numerics.md."""

from hwsim.numerics.format import (
    OVERFLOWS,
    ROUNDINGS,
    SATURATIONS,
    FixedFormat,
    OverflowError_,
    SaturationLog,
    mul,
    rescale,
    round_shift,
)
from hwsim.numerics.metrics import max_abs_error, per_channel, psnr, rmse, ulp_distance

__all__ = [
    "OVERFLOWS",
    "ROUNDINGS",
    "SATURATIONS",
    "FixedFormat",
    "OverflowError_",
    "SaturationLog",
    "max_abs_error",
    "mul",
    "per_channel",
    "psnr",
    "rescale",
    "rmse",
    "round_shift",
    "ulp_distance",
]
