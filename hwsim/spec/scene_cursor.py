"""The scene's ``[cursor]``: VolumePro 500's hardware 3-D cursor.

# Ref: architectures.md section 3 (VolumePro 500: "hardware crosshair or plane cursor,
#      widths 1/3/5/7 voxels, per-axis colour/opacity", [V] vli.h ``VLICursor``: types
#      kCrossHair / kPlane, SetWidth 1, 3, 5 or 7, SetLength (0 = infinite), SetPosition
#      in object space, flags kEnableX/Y/Z, kExcludeOverlap, kDisableCrop, per-axis
#      SetColor / SetOpacity 0..1, packed 0..255; "not supported on the VolumePro 1000").

What the table means (the geometry is :mod:`hwsim.golden.cursor`, the arithmetic
:mod:`models.units.cursor`)::

    [cursor]
    type = "crosshair"        # crosshair: three bars through position, one per axis
                              # plane: three planes through position, one per axis
    position = [32, 40, 20]   # (x, y, z) voxel index coordinates
    width = 1                 # 1, 3, 5 or 7 voxels across a bar or plane
    length = 0                # voxels along a bar (across a plane); 0 = infinite
    exclude_overlap = false   # true: samples on two or more bars show no cursor
    disable_crop = true       # true: the cursor shows where crop or cut planes remove
                              # the volume (VTK's VolumePro mappers always set it)
    [cursor.x]                # the bar along x (the plane across x); also y, z
    color = [1, 0, 0]         # defaults: x red, y green, z blue
    opacity = 1.0
    enabled = true
"""

from __future__ import annotations

from dataclasses import dataclass

from hwsim.spec.scene_schema import CURSOR_TYPES, CURSOR_WIDTHS, CursorModel, given

__all__ = ["CURSOR_TYPES", "CURSOR_WIDTHS", "CursorAxis", "CursorSpec", "parse_cursor"]

_DEFAULT_COLORS = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


@dataclass(frozen=True, kw_only=True)
class CursorAxis:
    """One axis's bar (crosshair) or plane (plane cursor): colour and opacity 0..1."""

    color: tuple[float, float, float]
    opacity: float = 1.0
    enabled: bool = True


@dataclass(frozen=True, kw_only=True)
class CursorSpec:
    """A hardware 3-D cursor (see the module docstring for the keys)."""

    type: str = "crosshair"
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    width: int = 1
    length: float = 0.0
    exclude_overlap: bool = False
    disable_crop: bool = True
    x: CursorAxis = CursorAxis(color=_DEFAULT_COLORS["x"])
    y: CursorAxis = CursorAxis(color=_DEFAULT_COLORS["y"])
    z: CursorAxis = CursorAxis(color=_DEFAULT_COLORS["z"])

    @property
    def axes(self) -> tuple[CursorAxis, CursorAxis, CursorAxis]:
        """The x, y and z axes, in that order (bar ``k`` runs along axis ``k``)."""
        return (self.x, self.y, self.z)


def parse_cursor(m: CursorModel) -> CursorSpec:
    """A :class:`CursorSpec` from a validated ``[cursor]`` table (its keys' types and
    ranges: :class:`hwsim.spec.scene_schema.CursorModel`)."""
    axes = {
        name: CursorAxis(**{"color": _DEFAULT_COLORS[name], **given(getattr(m, name))})
        for name in ("x", "y", "z")
    }
    return CursorSpec(**given(m) | axes)
