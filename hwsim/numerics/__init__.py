"""Fixed-point formats (rounding, saturation) and error metrics.  See docs/numerics.md."""

from hwsim.numerics.format import (
    OVERFLOWS,
    ROUNDING_CODES,
    ROUNDINGS,
    SATURATIONS,
    FixedFormat,
    OverflowError_,
    SaturationLog,
    mul,
    rescale,
    round_scaled,
    round_shift,
    round_shift_raw,
)
from hwsim.numerics.metrics import (
    EXACT_MATCHES,
    ROUND_OFF,
    agreement,
    max_abs_error,
    per_channel,
    psnr,
    rmse,
    ulp_distance,
)

__all__ = [
    "EXACT_MATCHES",
    "ROUND_OFF",
    "agreement",
    "OVERFLOWS",
    "ROUNDING_CODES",
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
    "round_scaled",
    "round_shift",
    "round_shift_raw",
    "ulp_distance",
]
