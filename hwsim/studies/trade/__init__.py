"""Measured trades: the fidelity ladder (speed against error per rung, on what each machine
has: plan.py chooses the cells, table.py prints them) and bit widths.

# Ref: shared/docs/design.md section 3 (the fidelity ladder; numerical vs algorithmic error).
"""

from hwsim.studies.trade.ladder import TradeCase, ladder_cases, ladder_trade, write_ladder_trade
from hwsim.studies.trade.plan import TradeRows
from hwsim.studies.trade.widths import (
    WIDTH_KNOBS,
    WidthCase,
    default_cases,
    width_trade,
    write_width_trade,
)

__all__ = [
    "WIDTH_KNOBS",
    "TradeCase",
    "TradeRows",
    "WidthCase",
    "default_cases",
    "ladder_cases",
    "ladder_trade",
    "width_trade",
    "write_ladder_trade",
    "write_width_trade",
]
