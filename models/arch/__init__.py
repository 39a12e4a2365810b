"""Architecture assemblies and their configs (cube4, em-cube, volumepro500, volumepro1000, vizard2)."""
