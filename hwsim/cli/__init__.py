"""The command line, a thin shell over the library (``hwsim = "hwsim.cli:main"``)."""


def __getattr__(name: str):
    # The console script's entry point, imported on first use (the CLI's modules import
    # this package; importing main here eagerly would import them all in a circle).
    if name == "main":
        try:
            from hwsim.cli.commands import main
        except KeyboardInterrupt:  # Ctrl-C while the command line is still importing
            from hwsim.core import interrupt

            interrupt.say()
            raise SystemExit(interrupt.EXIT_STATUS) from None
        return main
    raise AttributeError(f"module 'hwsim.cli' has no attribute {name!r}")
