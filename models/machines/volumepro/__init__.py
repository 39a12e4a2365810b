"""The VolumePro family (VolumePro 500, EM-Cube, VolumePro 1000): slab cycle machine, its
timing, SDRAM volume layout, transaction models and architecture files."""
