"""The Cube-4 family: cycle model, skewed memory, slice datapath, transaction model and
its architecture files (``cube4.toml``, ``cube4-teramac.toml``)."""
