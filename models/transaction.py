"""The ``transaction`` rung: the functional image, timed by a SimPy event model.

# Ref: design.md section 3 (transaction rung: image = functional; timing from a SimPy
#      event model at beam/burst granularity, its error against the cycle rung measured
#      and bounded per architecture); docs/transaction.md.

The image is the functional rung's (:func:`models.functional.render_functional`, called,
not duplicated), so it is bit-identical to the functional and cycle images.  The cycle
count comes from a discrete-event model of the machine at a coarser granularity than the
cycle rung (slices, beam batches, pixel rows), which never calls the cycle machine.  The
model is the one the registry (:mod:`models.machines`) holds for the architecture's
processing order: the Cube-4 family's slices and beams, the VolumePro family's SDRAM-fed
slabs (sections, and beam skipping on VolumePro 1000, which reads each ray's termination
step from the functional rung's result), VIZARD II's ray packets and block-cache misses.
Others raise :class:`~hwsim.core.errors.NotAvailableError` naming what is modelled.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hwsim.core.errors import InputError, NotAvailableError
from hwsim.engine.metrics import derive
from hwsim.spec.arch import ArchConfig
from models.frame import Frame
from models.functional import render_functional
from models.machines import families, machine_for

__all__ = [
    "transaction_orders",
    "TransactionResult",
    "has_transaction_model",
    "render_transaction",
    "transaction_model",
    "transaction_timing",
    "termination_pass",
    "timing_only",
]


@dataclass
class TransactionResult:
    """Image (the functional rung's; None timing only), samples, the event model's cycles
    and counters."""

    image: np.ndarray | None
    samples: int
    rays: int
    cycles: int
    counters: dict[str, Any] = field(default_factory=dict)
    derived: dict[str, Any] = field(default_factory=dict)


def transaction_orders() -> tuple[str, ...]:
    """Processing orders with a transaction model."""
    return tuple(o for m in families() if m.transaction is not None for o in m.orders)


def has_transaction_model(arch: ArchConfig) -> bool:
    """Whether the transaction rung models ``arch`` (its machine family)."""
    try:
        return machine_for(arch).transaction is not None
    except NotAvailableError:
        return False


def transaction_model(frame: Frame, *, stopped: np.ndarray | None = None, **options: Any):
    """The event model of ``frame``'s architecture (not yet run).

    ``options`` go to the machine's model: ``pixel_fifo_depth`` (every family),
    ``groups`` and ``steady_state`` (VolumePro family; refused elsewhere).  ``stopped``
    (:attr:`models.functional.FunctionalResult.stopped` of the frame) saves the models
    that read the rays' ends (VolumePro 1000, VIZARD II) rendering the functional rung
    for them; the others do not read it.
    """
    arch = frame.arch
    machine = machine_for(arch, "transaction")
    if options.get("steady_state") and not machine.steady_state:
        raise InputError(
            f"{arch.name} ({arch.order} order) times single frames only",
            key="steady_state",
            allowed="a machine of order "
            + ", ".join(o for m in families() if m.steady_state for o in m.orders),
        )
    if not machine.steady_state:
        options.pop("steady_state", None)
    model = machine.transaction(frame, **options)
    if getattr(model, "READS_THE_FRAME", False):
        model.stopped = stopped
    return model


def transaction_timing(frame: Frame, **options: Any):
    """Run only the event model of ``frame``'s architecture (no image).

    A machine whose rays may stop early renders the functional rung for their
    termination steps unless ``stopped=`` gives them.

    Returns
    -------
    models.machines.common.transaction.TxnTiming
        Cycles and counters (:func:`transaction_model` for ``options``).
    """
    return transaction_model(frame, **options).run()


def termination_pass(frame: Frame):
    """The functional rung on ``frame`` unlit: what an event model that reads the rays'
    ends (early ray termination, iso hits) needs, without gradients or shading (neither
    changes a sample's opacity; gradient-magnitude opacity modulation still computes its
    gradients).  Returns the :class:`~models.functional.FunctionalResult`."""
    scene = frame.scene
    if scene.lit:
        unlit = scene.replace(render=dataclasses.replace(scene.render, lighting=False))
        frame = dataclasses.replace(frame, scene=unlit)
    return render_functional(frame)


def timing_only(
    frame: Frame,
    *,
    steady_state: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> TransactionResult:
    """The transaction rung without the image (``--timing-only``, sweeps): the event model
    alone, fed the rays' ends by :func:`termination_pass` where it reads them.  ``samples``
    is the model's own count (``frame.samples``; else the plan's), ``rays`` the plan's.
    ``progress(done, total)`` counts the event model's work items (slices, beam groups,
    ray packets)."""
    model = transaction_model(frame, steady_state=steady_state)
    model.progress = progress
    if getattr(model, "READS_THE_FRAME", False):
        model.ends = termination_pass  # run only if the model asks (its rays may stop)
    timing = model.run()
    counters = dict(timing.counters)
    samples = int(counters.get("frame.samples", frame.plan.samples))
    derived = derive(
        counters,
        cycles=timing.cycles,
        samples=samples,
        pipelines=frame.arch.pipelines,
        clock_hz=frame.arch.clock_hz,
    )
    return TransactionResult(
        image=None,
        samples=samples,
        rays=int(frame.plan.ray_ids.size),
        cycles=timing.cycles,
        counters=counters,
        derived=derived,
    )


def render_transaction(
    frame: Frame,
    *,
    progress: Callable[[int, int], None] | None = None,
    steady_state: bool = False,
) -> TransactionResult:
    """Render ``frame``: functional image, cycles from its architecture's event model.

    The event model is built first, so a machine without one (or a scene it refuses)
    fails before the image is computed; it runs after the image, whose per-ray
    termination steps a machine with early-ray-termination hardware needs.
    ``counters["transaction.timing_seconds"]`` and ``["transaction.image_seconds"]``
    split the wall time between the two parts.  ``progress(done, total)`` runs over both:
    the image's steps, then the event model's work items scaled to as many steps.
    ``steady_state`` (VolumePro family) also plays a second frame back to back:
    ``counters["frame.period_cycles"]``, as the cycle rung's rule 9.
    """
    model = transaction_model(frame, steady_state=steady_state)
    image_part, model.progress, finish = _image_then_timing(progress)
    start = time.perf_counter()
    image = render_functional(frame, progress=image_part)
    image_seconds = time.perf_counter() - start
    if getattr(model, "READS_THE_FRAME", False):
        model.stopped = image.stopped  # the rays' termination steps (ERT hardware)
    timing = model.run()
    finish()
    counters = dict(timing.counters)
    counters["transaction.image_seconds"] = image_seconds
    counters["functional.saturated"] = image.counters.get("functional.saturated", {})
    derived = derive(
        counters,
        cycles=timing.cycles,
        samples=image.samples,
        pipelines=frame.arch.pipelines,
        clock_hz=frame.arch.clock_hz,
    )
    return TransactionResult(
        image=image.image,
        samples=image.samples,
        rays=image.rays,
        cycles=timing.cycles,
        counters=counters,
        derived=derived,
    )


def _image_then_timing(progress: Callable[[int, int], None] | None):
    """``progress`` split in two halves of one scale: a callback for the functional image
    (its steps), one for the event model (its work items, scaled to as many steps as
    the image had) and ``finish()``, which reports the whole (a model with no work items
    reports none)."""
    if progress is None:
        return None, None, lambda: None
    steps = [0]

    def image(done: int, total: int) -> None:
        steps[0] = total
        progress(done, 2 * total)

    def timing(done: int, total: int) -> None:
        n = steps[0] or total
        progress(n + n * done // max(total, 1), 2 * n)

    def finish() -> None:
        n = max(steps[0], 1)
        progress(2 * n, 2 * n)

    return image, timing, finish
