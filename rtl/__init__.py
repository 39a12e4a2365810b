"""Amaranth RTL of the key units, one module per ``models.units`` module."""
