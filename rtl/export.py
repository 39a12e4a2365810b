"""Verilog export of a unit: Amaranth's built-in Yosys, ports named ``i__payload`` etc.

Always-ready streams (the table ``load`` ports) have a constant ``ready``: it is not a
port of the Verilog module.
"""

from __future__ import annotations

from amaranth.back import verilog
from amaranth.hdl import Const, Value, ValueCastable
from amaranth.hdl._ir import PortDirection
from amaranth.lib import wiring

__all__ = ["ports_of", "to_verilog"]


def ports_of(component: wiring.Component) -> dict:
    """``{"i__payload": (signal, direction), ...}`` of every non-constant member."""
    ports = {}
    for path, member, value in component.signature.flatten(component):
        if isinstance(value, ValueCastable):
            value = value.as_value()
        value = Value.cast(value)
        if isinstance(value, Const):
            continue
        direction = PortDirection.Input if member.flow == wiring.In else PortDirection.Output
        ports["__".join(map(str, path))] = (value, direction)
    return ports


def to_verilog(component: wiring.Component, name: str) -> str:
    """The unit as a Verilog module ``name`` (no ``timescale``; simulators set one)."""
    return verilog.convert(component, name=name, ports=ports_of(component), emit_src=False)
