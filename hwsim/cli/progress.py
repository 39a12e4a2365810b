"""The command line's progress bar: one tqdm bar that stays silent for work under a second."""

from __future__ import annotations

import sys

__all__ = ["progress_bar"]


class progress_bar:
    """A tqdm bar with an ETA that appears only when the work takes over a second.

    The callback is ``update(done, total)``, or ``update(done, total, what)`` to name
    the part under way.
    """

    def __init__(self, quiet: bool, label: str, unit: str = "step") -> None:
        self.quiet, self.label, self.unit, self.bar = quiet, label, unit, None

    def __enter__(self):
        if self.quiet:
            return None
        return self._update

    def _update(self, done: int, total: int, what: str | None = None) -> None:
        if self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(
                total=total,
                desc=self.label,
                unit=self.unit,
                unit_scale=self.unit != "step",
                delay=1.0,  # keeps short renders silent
                leave=False,
                file=sys.stderr,
            )
        if what is not None:
            self.bar.set_postfix_str(what, refresh=False)
        self.bar.update(done - self.bar.n)

    def __exit__(self, *exc) -> None:
        if self.bar is not None:
            self.bar.close()
