"""Architecture assemblies and their configs.

Built-in machines: cube4, cube4-teramac, em-cube, volumepro500, volumepro1000, vizard2.
"""
