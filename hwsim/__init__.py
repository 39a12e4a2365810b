"""hwsim: a cycle-level simulator of Cube-4 / VolumePro-style volume-rendering hardware.

The Python API (docs/api.md; defined in :mod:`hwsim.api`, imported on first use so that
``import hwsim`` stays cheap)::

    import hwsim
    run = hwsim.render(hwsim.load_scene("head"), fidelity="functional", arch="volumepro500")
    print(run.cycles)
"""

__version__ = "0.1.0"

__all__ = [
    "__version__",
    "HwsimError",
    "InputError",
    "Run",
    "SweepResult",
    "arch",
    "archs",
    "load_scene",
    "load_volume",
    "render",
    "sweep",
    "trade",
]

_ERRORS = ("HwsimError", "InputError")


def __getattr__(name: str):
    """The API's names, imported from :mod:`hwsim.api` when first asked for."""
    if name in _ERRORS:
        from hwsim.core import errors

        return getattr(errors, name)
    if name in __all__:
        from hwsim import api

        return getattr(api, name)
    raise AttributeError(f"module 'hwsim' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*(n for n in globals() if not n.startswith("_")), *__all__})
