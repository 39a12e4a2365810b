"""SDR SDRAM device model and datasheet timing checker (Verilog), and their Python runner.

``sdr_sdram.v`` (the device), ``sdram_checker.v`` (the timing checker on the same pins),
``sdram_tb.v`` (a testbench replaying a command trace into both) and :mod:`rtl.sdram.sim`
(build, run, read the counts).  Pins: docs/memory.md "The SDRAM checker".
"""
