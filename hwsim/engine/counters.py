"""Raw counters under component paths (``pipeline[2].interp.busy_cycles``).

Only raw event counts live here; ratios and rates are derived in
:mod:`hwsim.engine.metrics`, in one place (conventions.md item 7).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

__all__ = ["Counters"]


class Counters:
    """An ordered map from component path to a non-negative integer count."""

    def __init__(self) -> None:
        self._values: dict[str, int] = {}

    def add(self, path: str, amount: int | np.integer = 1) -> None:
        """Add ``amount`` (>= 0) to ``path``, creating it at 0."""
        amount = int(amount)
        if amount < 0:
            raise ValueError(f"counter {path}: negative increment {amount}")
        self._values[path] = self._values.get(path, 0) + amount

    def add_lanes(self, path: str, amounts: np.ndarray) -> None:
        """Add ``amounts[i]`` to the counter ``path`` with ``{i}`` formatted as the lane."""
        for lane, amount in enumerate(np.asarray(amounts).tolist()):
            self.add(path.format(lane), amount)

    def set(self, path: str, value: int) -> None:
        self._values[path] = int(value)

    def __getitem__(self, path: str) -> int:
        return self._values[path]

    def get(self, path: str, default: int = 0) -> int:
        return self._values.get(path, default)

    def __contains__(self, path: str) -> bool:
        return path in self._values

    def __iter__(self) -> Iterator[str]:
        return iter(self._values)

    def items(self):
        return self._values.items()

    def matching(self, suffix: str) -> dict[str, int]:
        """Counters whose path ends with ``suffix``."""
        return {k: v for k, v in self._values.items() if k.endswith(suffix)}

    def as_dict(self) -> dict[str, int]:
        return dict(self._values)
