"""Texture-slicing graphics hardware (2-D texture stacks, 3-D textures with view-aligned
slices), the machine family ``texslicer``: architecture files ``texture-slicer*.toml``."""
