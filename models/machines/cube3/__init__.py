"""Cube-3: skewed volume memory, a de-skewing network, parallel units, a compositing tree."""
