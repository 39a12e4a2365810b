"""The framework's floor: errors, validated TOML, output paths, the memory budget,
thread counts and Dask clients."""
