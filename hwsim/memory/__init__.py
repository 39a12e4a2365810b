"""Volume memory timing: SDRAM parameters, a cycle-exact scheduler and a SimPy event form.

See docs/memory.md.  The voxel layouts (which module, bank and row a voxel lives in) are
the architecture's business (models/units/skew.py, models/memory_streams.py); this
package only times the burst streams they produce.
"""

from hwsim.memory.sdram import PAGE_POLICIES, SKEWS, MemoryConfig, SdramConfig, parse_memory
from hwsim.memory.sdram_cycle import (
    CONFLICT,
    HIT,
    MISS,
    BurstSchedule,
    SdramController,
    SdramStats,
    schedule_bursts,
    summarize,
)
from hwsim.memory.sdram_events import (
    BurstRequest,
    SdramEventModel,
    SdramTransactionPort,
    simulate_events,
)

__all__ = [
    "CONFLICT",
    "HIT",
    "MISS",
    "PAGE_POLICIES",
    "SKEWS",
    "BurstRequest",
    "BurstSchedule",
    "MemoryConfig",
    "SdramConfig",
    "SdramController",
    "SdramEventModel",
    "SdramStats",
    "SdramTransactionPort",
    "parse_memory",
    "schedule_bursts",
    "simulate_events",
    "summarize",
]
