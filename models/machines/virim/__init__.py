"""VIRIM: boards of a table-driven resampling unit and a programmable ray-casting unit,
each board rendering its share of the image from its own copy of the volume."""
