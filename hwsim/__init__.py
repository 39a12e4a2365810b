"""hwsim: a cycle-level simulator of Cube-4 / VolumePro-style volume-rendering hardware.

The Python API (docs/api.md; defined in :mod:`hwsim.api`, imported on first use so that
``import hwsim`` stays cheap)::

    import hwsim
    run = hwsim.render(hwsim.load_scene("head"), fidelity="functional", arch="volumepro500")
    print(run.cycles)
"""

import sys
import types

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
        from hwsim import errors

        return getattr(errors, name)
    if name in __all__:
        from hwsim import api

        return getattr(api, name)
    raise AttributeError(f"module 'hwsim' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*(n for n in globals() if not n.startswith("_")), *__all__})


class _Entry:
    # ``hwsim.arch``, ``hwsim.sweep`` and ``hwsim.trade`` name both an API function and a
    # module (hwsim/arch.py, hwsim/sweep/, hwsim/trade/).  Calling this runs the function;
    # any attribute is the module's (``hwsim.sweep.spec``, ``hwsim.arch.ArchConfig``), so
    # both keep working; help() and inspect.signature() show the function.

    __doc__ = property(lambda self: self.__wrapped__.__doc__)  # type: ignore[assignment]

    def __init__(self, name: str) -> None:
        object.__setattr__(self, "_name", name)

    def __call__(self, *args, **kwargs):
        from hwsim import api

        return getattr(api, self._name)(*args, **kwargs)

    def _package(self) -> types.ModuleType:
        import importlib

        return importlib.import_module(f"hwsim.{self._name}")

    def __getattr__(self, attr: str):
        if attr in ("__wrapped__", "__signature__"):
            from hwsim import api

            function = getattr(api, self._name)
            return function if attr == "__wrapped__" else getattr(function, attr)
        return getattr(self._package(), attr)

    def __setattr__(self, attr: str, value) -> None:
        setattr(self._package(), attr, value)

    def __repr__(self) -> str:
        return f"<function hwsim.{self._name} (and package hwsim.{self._name})>"


class _Package(types.ModuleType):
    """The ``hwsim`` module: importing ``hwsim.arch``, ``hwsim.sweep.*`` or
    ``hwsim.trade.*`` (Python then sets the attribute of that name) must not replace the
    API functions of those names with the modules."""

    arch = property(lambda self: _Entry("arch"), lambda self, value: None)
    sweep = property(lambda self: _Entry("sweep"), lambda self, value: None)
    trade = property(lambda self: _Entry("trade"), lambda self, value: None)


sys.modules[__name__].__class__ = _Package
