"""Multi-LUT classification in float64: voxel fields, per-LUT transfer functions, and the
real-valued counterpart of every combiner opcode.

# Ref: architectures.md section 4 (VolumePro 1000 classifier: up to 4 LUTs, two leaf
#      combiners + a final one); the fixed-point unit is models/units/combine.py.

Operands are in ``[0, 1]``.  ``add`` = ``min(a + b, 1)``, ``sub`` = ``max(a - b, 0)``,
``rsub`` = ``max(b - a, 0)``, ``min``/``max``, ``mulK`` = ``min(K a b, 1)``,
``mul_b_alpha`` = ``a * alpha_b``.  The logic opcodes (``and``, ``or``, ``xor``) have no
real-valued meaning: they are evaluated on the operands quantised to the stored widths
(unorm 8-bit colour, 12-bit alpha, as the hardware holds them) and the result continues
in float64.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hwsim.spec.scene import Scene
from hwsim.spec.scene_features import VALUE_FIELD, ClassificationSpec
from hwsim.spec.transfer import TransferFunction, resolve_transfer
from hwsim.volumes.volume import Volume

__all__ = ["FloatClassifier", "field_values", "float_alu"]

_PRODUCTS = {"mul": 1.0, "mul2": 2.0, "mul4": 4.0, "mul8": 8.0}


def field_values(volume: Volume, lsb: int, bits: int) -> np.ndarray:
    """Raveled ``(volume >> lsb) & (2**bits - 1)`` of unsigned integer data (the whole
    voxels of a field's volume, ``meta["container"]``), float64."""
    data = np.asarray(volume.meta.get("container", volume.data))
    raw = (data.astype(np.int64) >> lsb) & ((1 << bits) - 1)
    return raw.astype(np.float64).ravel()


def float_alu(op: str, a: np.ndarray, b: np.ndarray, stored_bits: int) -> np.ndarray:
    """The real-valued opcode ``op`` on operands in ``[0, 1]`` (logic ops on the values
    quantised to ``stored_bits``)."""
    if op == "a":
        return a
    if op == "b":
        return b
    if op in ("and", "or", "xor"):
        full = (1 << stored_bits) - 1
        qa = np.floor(a * full + 0.5).astype(np.int64)
        qb = np.floor(b * full + 0.5).astype(np.int64)
        q = {"and": qa & qb, "or": qa | qb, "xor": qa ^ qb}[op]
        return q / full
    if op == "add":
        return np.minimum(a + b, 1.0)
    if op == "sub":
        return np.maximum(a - b, 0.0)
    if op == "rsub":
        return np.maximum(b - a, 0.0)
    if op == "min":
        return np.minimum(a, b)
    if op == "max":
        return np.maximum(a, b)
    if op in _PRODUCTS:
        return np.minimum(_PRODUCTS[op] * a * b, 1.0)
    raise ValueError(f"unknown combiner opcode {op!r}")


def _apply(ops: tuple[str, str], x: np.ndarray, y: np.ndarray, bits: tuple[int, int]):
    rgb_op, alpha_op = ops
    out = np.empty_like(x)
    if rgb_op == "mul_b_alpha":
        out[:, :3] = x[:, :3] * y[:, 3:4]
    else:
        out[:, :3] = float_alu(rgb_op, x[:, :3], y[:, :3], bits[0])
    if alpha_op == "mul_b_alpha":
        out[:, 3] = x[:, 3] * y[:, 3]
    else:
        out[:, 3] = float_alu(alpha_op, x[:, 3], y[:, 3], bits[1])
    return out


class FloatClassifier:
    """The scene's LUT functions and combiner tree, evaluated in float64.

    Parameters
    ----------
    scene : Scene
        A scene with a ``[classification]`` section.
    volume : Volume
        Its volume (declared fields need unsigned integer data).
    base_dir : Path, optional
        Where relative ``table`` paths of the LUT functions are resolved.
    stored_bits : (int, int)
        Colour and alpha widths the logic opcodes quantise to.
    """

    def __init__(
        self,
        scene: Scene,
        volume: Volume,
        base_dir: Path | None = None,
        stored_bits: tuple[int, int] = (8, 12),
    ) -> None:
        spec: ClassificationSpec = scene.classification  # type: ignore[assignment]
        self.spec, self.stored_bits = spec, stored_bits
        self.tfs: list[TransferFunction] = [
            resolve_transfer(lut.transfer, volume, base_dir)  # type: ignore[arg-type]
            for lut in spec.luts
        ]
        self.field_names = sorted({lut.field for lut in spec.luts if lut.field != VALUE_FIELD})
        self.flat_fields = {}
        for name in self.field_names:
            f = spec.field(name)
            self.flat_fields[name] = field_values(volume, f.lsb, f.bits)  # type: ignore[union-attr]

    def classify(self, inputs: dict[str, np.ndarray]) -> np.ndarray:
        """Combined RGBA ``(n, 4)`` from per-field sample values (``inputs[name]``; the
        ``value`` field in the volume's units, declared fields in field integers)."""
        outs = [
            tf.classify(inputs[lut.field]) for lut, tf in zip(self.spec.luts, self.tfs, strict=True)
        ]
        if len(outs) == 1:
            return outs[0]
        outs += [np.zeros_like(outs[0])] * (4 - len(outs))
        s = self.spec
        left = _apply(s.leaf0.ops, outs[0], outs[1], self.stored_bits)
        right = _apply(s.leaf1.ops, outs[2], outs[3], self.stored_bits)
        return _apply(s.final.ops, left, right, self.stored_bits)
