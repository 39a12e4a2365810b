"""One module per hardware unit: bit-exact arithmetic, latency, initiation interval."""
