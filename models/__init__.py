"""The hardware being modelled.

``models.units``: unit arithmetic; ``models.arch``: assemblies and machine configs.
"""
