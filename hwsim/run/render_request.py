"""One render request: the options of :func:`hwsim.run.fidelity.render`, validated once.

A :class:`RenderRequest` is frozen and refuses, when it is made, every combination of
options that no rung renders (an option of another rung, a split frame that cannot be
split), with the one-line :class:`~hwsim.core.errors.InputError` the CLI prints.  What needs
the machine or the volume (the machine's sample order, a supervolume's bricks) is refused
by :meth:`RenderRequest.refuse_order` and :meth:`RenderRequest.refuse_bricks` once those
are known.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hwsim.core.errors import InputError
from hwsim.spec.arch import ArchConfig
from hwsim.volumes.volume import Volume

__all__ = ["FIDELITIES", "SAMPLINGS", "MAX_WORKERS", "DEFAULT_ARCH", "RenderRequest"]

FIDELITIES = ("golden", "functional", "transaction", "cycle", "rtl")
#: Most workers (and bands) one frame is split across.
MAX_WORKERS = 256
#: The machine a timed rung models when no --arch is given.
DEFAULT_ARCH = "volumepro500"
SAMPLINGS = ("ray", "shear-warp", "shear-image", "slice-parallel")

Progress = Callable[[int, int], None]


@dataclass(frozen=True, kw_only=True)
class RenderRequest:
    """How to render a scene (the keywords of :func:`hwsim.run.fidelity.render`), refused at
    construction if no rung renders it (:meth:`validate`).

    Attributes
    ----------
    fidelity : str
        One of :data:`FIDELITIES`.
    arch : str or ArchConfig, optional
        Architecture name, file or config (a sweep's overrides).  At the golden rung
        it selects the machine's sample positions (so golden vs. a timed rung differs
        only numerically).
    sampling : str
        Sample positions of the golden rung without ``arch``: the ideal ``ray`` caster
        or an architecture's (``shear-warp``, ``shear-image``, ``slice-parallel``).
    volume : Volume, optional
        An already loaded volume (skips loading ``scene.volume``).
    progress : callable, optional
        ``progress(done, total)`` called as the render advances.
    trace : path, optional
        ``cycle`` and ``rtl`` rungs: write a VCD waveform of the modelled hardware there.
    elaborate_all : bool
        ``cycle`` rung only: simulate every unit, even those the scene does not use (the
        reference that elision is measured against; same image and cycles).
    steady_state : bool
        ``cycle`` and ``transaction`` rungs, VolumePro family: also time the next frame
        back to back (``frame.period_cycles`` in the counters: the continuous frame rate).
    simulator : str, optional
        ``rtl`` rung only: ``verilator`` (the default) or ``icarus``.
    extend : bool
        Render a scene outside the machine's declared features as a what-if (listed in
        ``extensions``) instead of refusing it (:mod:`hwsim.spec.machine_features`).
    timing_only : bool
        ``transaction`` rung only: time the frame without its image (``image`` is None;
        :func:`models.transaction.timing_only`).
    technology : str, optional
        ``cycle`` and ``transaction`` rungs: price the frame's actions and the machine's
        area in this technology (a built-in name or a TOML file; default: the machine's
        ``[silicon] technology``), :mod:`hwsim.energy`.
    workers, scheduler, bands : optional
        ``cycle`` rung: split the frame across a local Dask cluster of ``workers``
        processes, or the cluster at ``scheduler``, in ``bands`` bands of rays (default:
        one per worker), reading the volume in parts (:mod:`hwsim.run.frame_split`); the same
        image, cycles and counters as one process.  What the split did is ``split``.
    """

    fidelity: str = "golden"
    arch: str | ArchConfig | None = None
    sampling: str = "ray"
    volume: Volume | None = None
    progress: Progress | None = None
    trace: str | Path | None = None
    elaborate_all: bool = False
    steady_state: bool = False
    simulator: str | None = None
    extend: bool = False
    timing_only: bool = False
    technology: str | None = None
    workers: int | None = None
    scheduler: str | None = None
    bands: int | None = None

    def __post_init__(self) -> None:
        self.validate()

    @classmethod
    def of(cls, request: RenderRequest | None = None, **keywords: Any) -> RenderRequest:
        """``request`` with ``keywords`` replacing its fields (validated again), or a
        request made of ``keywords`` alone."""
        if request is None:
            return cls(**keywords)
        return dataclasses.replace(request, **keywords) if keywords else request

    @property
    def split(self) -> bool:
        """Whether the frame is split across workers (:mod:`hwsim.run.frame_split`)."""
        return self.workers is not None or self.scheduler is not None

    @property
    def machine(self) -> str | ArchConfig | None:
        """The machine asked for: ``arch``, or :data:`DEFAULT_ARCH` at a timed rung."""
        if self.arch is None and self.fidelity != "golden":
            return DEFAULT_ARCH
        return self.arch

    def validate(self) -> None:
        """Refuse options no rung renders, in the order the CLI reports them."""
        fidelity = self.fidelity
        if fidelity not in FIDELITIES:
            raise InputError(
                f"unknown fidelity {fidelity!r}", key="--fidelity", allowed=", ".join(FIDELITIES)
            )
        if self.steady_state and fidelity not in ("cycle", "transaction"):
            raise InputError(
                "only the cycle and transaction rungs time back-to-back frames",
                key="steady_state",
                allowed="cycle, transaction",
            )
        if self.timing_only and fidelity != "transaction":
            raise InputError(
                "only the transaction rung times a frame without its image",
                key="--timing-only",
                allowed="--fidelity transaction",
            )
        if self.elaborate_all and fidelity != "cycle":
            raise InputError("only the cycle rung elaborates units", key="elaborate_all")
        if self.trace is not None and fidelity not in ("cycle", "rtl"):
            raise InputError(
                "a waveform needs --fidelity cycle or rtl", key="--trace", allowed="cycle, rtl"
            )
        if self.simulator is not None and fidelity != "rtl":
            raise InputError(
                "an HDL simulator runs the rtl rung only", key="--simulator", allowed="rtl"
            )
        if self.split:
            self._refuse_split()

    def _refuse_split(self) -> None:
        """Refuse what a frame split across workers cannot be."""
        workers, bands = self.workers, self.bands
        if self.fidelity != "cycle":
            raise InputError(
                f"the {self.fidelity} rung renders a frame in one process",
                key="--workers",
                allowed="--fidelity cycle",
            )
        if workers is not None and self.scheduler is not None:
            raise InputError(
                "give a worker count or a scheduler, not both",
                key="--workers",
                allowed="one of them",
            )
        if self.scheduler is not None:
            from hwsim.core.cluster import check_address

            check_address(self.scheduler)  # a bad scheme or port before any work
        if workers is not None and not (isinstance(workers, int) and 1 <= workers <= MAX_WORKERS):
            raise InputError(
                f"{workers!r} is out of range", key="--workers", allowed=f"1 .. {MAX_WORKERS}"
            )
        if bands is not None and not (isinstance(bands, int) and 1 <= bands <= MAX_WORKERS):
            raise InputError(
                f"{bands!r} is out of range", key="--bands", allowed=f"1 .. {MAX_WORKERS}"
            )
        if self.volume is not None:
            raise InputError(
                "a frame split across workers reads its volume in parts, not a loaded volume",
                key="volume",
                allowed="the scene's volume file or phantom",
            )
        for flag, given in (
            ("--elaborate-all", self.elaborate_all),
            ("--steady-state", self.steady_state),
        ):
            if given:
                raise InputError("renders in one process", key=flag, allowed="no --workers")

    def refuse_order(self, machine: ArchConfig | None) -> str:
        """The sample order the frame is rendered in: ``machine``'s, or ``sampling``
        (refused if neither ``ray`` nor the machine's order, or unknown)."""
        sampling = self.sampling
        if machine is not None:
            if sampling not in ("ray", machine.order):
                raise InputError(
                    f"{machine.name} samples in {machine.order} order",
                    key="--sampling",
                    allowed=f"{machine.order} (or omit it)",
                )
            sampling = machine.order
        if sampling not in SAMPLINGS:
            raise InputError(
                f"unknown sampling {sampling!r}", key="--sampling", allowed=", ".join(SAMPLINGS)
            )
        return sampling

    def refuse_bricks(self, machine: ArchConfig) -> None:
        """Refuse what a supervolume rendered in bricks of ``machine`` cannot be: timed
        without its image, or split across workers (beyond
        :func:`hwsim.run.supervolume.refuse_supervolume`)."""
        largest = f"a volume of at most {' x '.join(map(str, machine.max_volume))}"
        if self.timing_only:
            raise InputError(
                "a supervolume's host blend needs its bricks' images",
                key="--timing-only",
                allowed=largest,
            )
        if self.split:
            raise InputError(
                "a supervolume's bricks are frames of their own", key="--workers", allowed=largest
            )
