"""The command line, a thin shell over the library (``hwsim = "hwsim.cli:main"``)."""


def __getattr__(name: str):
    # The console script's entry point, imported on first use (the CLI's modules import
    # this package; importing main here eagerly would import them all in a circle).
    if name == "main":
        _exit_on_interrupt()
        from hwsim.cli.commands import main

        return main
    raise AttributeError(f"module 'hwsim.cli' has no attribute {name!r}")


def _exit_on_interrupt() -> None:
    """From the console script's first request for ``main`` until the command installs
    its own handler (``hwsim.core.interrupt.handling_sigint``), a Ctrl-C (the second or
    so of importing NumPy, Dask and numba, or the moment between the import and the call)
    prints ``hwsim: interrupted`` and exits 130 at once, never a traceback."""
    import signal
    import threading

    from hwsim.core import interrupt

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, interrupt.exit_now)
