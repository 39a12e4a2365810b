"""How a render runs: the fidelity ladder's request and dispatcher, split frames,
supervolume bricks, turntables, and what a run writes."""
