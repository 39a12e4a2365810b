"""The hardware being modelled: unit arithmetic (``models.units``) and assemblies (``models.arch``)."""
