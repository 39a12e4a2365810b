"""Volumes: the :class:`Volume` type, file readers and built-in phantoms.

One loader API: :func:`load_volume` takes a scene's :class:`~hwsim.spec.scene.VolumeSpec`
(a phantom or a file), :func:`read_volume` reads a file by extension, and
:func:`make_phantom` builds a phantom.  Axis order is ``(z, y, x)`` everywhere.
See ``docs/volumes.md``.
"""

from hwsim.volumes.phantoms import PHANTOMS, make_phantom, marschner_lobb, parse_phantom_spec
from hwsim.volumes.readers import EXTENSIONS, load_volume, read_volume
from hwsim.volumes.volume import SUPPORTED_DTYPES, Volume

__all__ = [
    "EXTENSIONS",
    "PHANTOMS",
    "SUPPORTED_DTYPES",
    "Volume",
    "load_volume",
    "make_phantom",
    "marschner_lobb",
    "parse_phantom_spec",
    "read_volume",
]
