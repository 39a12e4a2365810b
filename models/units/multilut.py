"""Multi-LUT classifier set-up and per-sample path: voxel fields, up to four LUTs, the
combiner tree, expansion to UQ1.12.

# Ref: architectures.md section 4 (VolumePro 1000: up to 4 voxel fields of 4..16 bits;
#      LUTs of 4096 or 256 entries, RGB 8-bit, alpha 12-bit; 3 combination ALUs).

Fields: the implicit ``value`` field is the whole voxel as the machine converts it
(``models.units.voxel``), its LUT built over the volume's units; a declared field is
bits ``lsb .. lsb + bits - 1`` of the stored unsigned integer voxel, its LUT built over
field integers ``0 .. 2**bits - 1``.  Declared fields need data the machine stores
unchanged up to a left shift (unsigned integers of at most the machine's voxel width),
so a field is the same bit range of every raw machine voxel, shifted.  Each field is
interpolated on its own (same taps, same :mod:`models.units.interp` arithmetic), so
neighbouring fields never mix.  A LUT of
``E`` entries on a field of ``b`` bits is indexed as :func:`classify.lut_index` does
(entry ``i`` stands for ``i 2**b / E``, nearest entry).  The LUT outputs (stored widths)
go through :func:`combine.combine_tree` and the result is expanded to UQ1.12.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from hwsim.core.errors import InputError
from hwsim.spec.scene import Scene
from hwsim.spec.scene_features import VALUE_FIELD
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes.volume import Volume
from models.units import classify as classify_unit
from models.units import combine
from models.units import interp as interp_unit
from models.units.classify import ClassifyConfig

__all__ = ["MultiLut"]


class MultiLut:
    """The LUTs, fields and combiner of one scene on one datapath.

    Parameters
    ----------
    scene, volume : Scene, Volume
        ``scene.classification`` must be set.
    voxel_bits : int
        The machine's voxel width (declared fields must fit in it).
    to_value : callable
        Raw voxel to volume units (the ``value`` field's LUT domain).
    cfg : ClassifyConfig
        Stored widths (``entries`` is replaced per LUT).
    """

    def __init__(
        self,
        scene: Scene,
        volume: Volume,
        voxel_bits: int,
        to_value: Callable[[np.ndarray], np.ndarray],
        cfg: ClassifyConfig,
    ) -> None:
        spec = scene.classification
        assert spec is not None
        self.spec, self.cfg, self.voxel_bits = spec, cfg, voxel_bits
        self.fields: dict[str, tuple[int, int]] = {}  # name -> (lsb in raw voxel, bits)
        data = volume.data
        #: The whole voxels of a field's volume (``Volume.field``: 32-bit containers):
        #: the declared fields are read from them, unshifted.
        self.container = volume.meta.get("container")
        stored = volume.bits if data.dtype.kind == "u" and volume.bits <= voxel_bits else 0
        shift = voxel_bits - volume.bits
        if stored and tuple(to_value(np.array([0.0, 1.0]))) != (0.0, 2.0**-shift):
            stored = 0  # not stored as is (left-shifted): fields would not be bit ranges
        if self.container is not None:
            if scene.transfer.order == "pre":
                raise InputError(
                    "pre-classification classifies the value path's voxels; the other "
                    "fields of a field container are post-classified",
                    source=scene.source,
                    key="transfer.order",
                    allowed="post",
                )
            data = self.container
            stored, shift = int(volume.meta["container_bits"]), 0
        for i, f in enumerate(spec.fields):
            if not any(lut.field == f.name for lut in spec.luts):
                continue
            if f.lsb + f.bits > stored:
                raise InputError(
                    f"field {f.name!r} (bits {f.lsb}..{f.lsb + f.bits - 1}) does not fit the "
                    f"stored voxel ({data.dtype} data of {volume.bits} bits, "
                    f"{voxel_bits}-bit machine voxels)",
                    source=scene.source,
                    key=f"classification.fields[{i}]",
                    allowed=f"unsigned integer data, lsb + bits <= {stored or 'its bits'}",
                )
            self.fields[f.name] = (f.lsb + shift, f.bits)
        self.luts, self.lut_cfgs, self.lut_bits = [], [], []
        for lut in spec.luts:
            tf = resolve_transfer(lut.transfer, volume, scene.base_dir)  # type: ignore[arg-type]
            c = dataclasses.replace(cfg, entries=lut.entries)
            if lut.field == VALUE_FIELD:
                bits, domain = voxel_bits, to_value
            else:
                bits, domain = self.fields[lut.field][1], _identity
            self.luts.append(classify_unit.build_lut(tf, domain, bits, c))
            self.lut_cfgs.append(c)
            self.lut_bits.append(bits)

    def field_raw(self, raw: np.ndarray) -> dict[str, np.ndarray]:
        """Raveled int64 values of every declared field the LUTs read, from raw machine
        voxels (any shape), or from the whole voxels of a field container."""
        source = raw if self.container is None else self.container
        r = np.asarray(source, dtype=np.int64).ravel()
        return {n: (r >> lsb) & ((1 << b) - 1) for n, (lsb, b) in self.fields.items()}

    def classify(
        self, inputs: dict[str, np.ndarray], frac_bits: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """Combined ``(rgb (n, 3), alpha (n,))`` in UQ1.12 from per-field samples with
        ``frac_bits`` fraction bits (``inputs[VALUE_FIELD]``: the raw voxel sample)."""
        outs = []
        for lut, c, bits, spec in zip(
            self.luts, self.lut_cfgs, self.lut_bits, self.spec.luts, strict=True
        ):
            i = classify_unit.lut_index(inputs[spec.field], bits, frac_bits, c)
            outs.append(combine.Rgba(np.take(lut.rgb, i, axis=0), lut.alpha[i]))
        s, cfg = self.spec, self.cfg
        out = combine.combine_tree(
            outs, s.leaf0.ops, s.leaf1.ops, s.final.ops, cfg.color_bits, cfg.alpha_bits
        )
        return classify_unit.expand(out.rgb, cfg.color_bits), classify_unit.expand(
            out.alpha, cfg.alpha_bits
        )

    def interpolate_fields(
        self, flats: dict[str, np.ndarray], zyx: np.ndarray, shape, icfg: interp_unit.InterpConfig
    ) -> dict[str, np.ndarray]:
        """Every declared field interpolated at ``zyx`` (``S`` fraction bits)."""
        if not flats:
            return {}
        taps = interp_unit.interp_taps(zyx, shape, icfg)
        return {n: interp_unit.interpolate(f, taps, icfg) for n, f in flats.items()}


def _identity(raw: np.ndarray) -> np.ndarray:
    return np.asarray(raw, dtype=np.float64)
