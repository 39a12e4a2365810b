"""The cycle kernel: clock, counters, ready/valid channels, delay lines, FIFOs, stages, VCD.

# Ref: design.md sections 2 and 3 (engine/, the ``cycle`` rung); conventions.md items 2,
#      3 and 7 (latency and II as interface, one ready/valid contract, raw counters).

The kernel is vectorised: a component advances over a *block* of cycles at once (a beam,
a slice) with NumPy arrays indexed by ``(lane, cycle)``, and every cycle inside the block
stays exact -- a delay line of depth D returns exactly what entered D cycles earlier, a
channel transfers exactly where ``valid & ready``.  Nothing here knows about volume
rendering; ``models.machines`` assembles machines from it.
"""

from hwsim.engine.channel import Channel
from hwsim.engine.clock import Clock
from hwsim.engine.counters import Counters
from hwsim.engine.delay import DelayLine
from hwsim.engine.fifo import DeadlockError, DrainFifo, FreezingFifoRun, freezing_fifo
from hwsim.engine.stage import Stage
from hwsim.engine.trace import VcdTrace

__all__ = [
    "Channel",
    "Clock",
    "Counters",
    "DeadlockError",
    "DelayLine",
    "DrainFifo",
    "FreezingFifoRun",
    "freezing_fifo",
    "Stage",
    "VcdTrace",
]
