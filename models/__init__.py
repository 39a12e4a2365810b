"""The hardware being modelled.

``models.units``: unit arithmetic; ``models.machines``: one package per machine family
behind one ``Machine`` interface (docs/architectures.md); the rest is the back end the
families share (datapath formats, functional rung, compositing back end).
"""
