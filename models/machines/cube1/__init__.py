"""Cube-1: the skewed cubic frame buffer (architectures.md section 1.1)."""
