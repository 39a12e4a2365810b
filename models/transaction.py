"""The ``transaction`` rung: the functional image, timed by a SimPy event model.

# Ref: design.md section 3 (transaction rung: image = functional; timing from a SimPy
#      event model at beam/burst granularity, its error against the cycle rung measured
#      and bounded per architecture); docs/transaction.md.

The image is the functional rung's (:func:`models.functional.render_functional`, called,
not duplicated), so it is bit-identical to the functional and cycle images.  The cycle
count comes from a discrete-event model of the machine at a coarser granularity than the
cycle rung (slices, beam batches, pixel rows), which never calls the cycle machine.
Machines with a transaction model, by processing order:

``slice-parallel``
    the Cube-4 family (:class:`models.arch.cube4_txn.Cube4Transaction`);
``shear-warp``, ``shear-image``
    the VolumePro family's SDRAM-fed slab machines
    (:class:`models.arch.volumepro_txn.SlabTransaction`): VolumePro 500 and EM-Cube,
    sections included; machines that skip beams (VolumePro 1000: early ray termination,
    space leaping) with :class:`models.arch.vp1000_txn.Vp1000Transaction`, which reads
    each ray's termination step from the functional rung's result;
``ray``
    VIZARD II (:class:`models.arch.vizard2_txn.VizardTransaction`): ray packets, the
    block cache's misses as SDRAM bursts, the pixel FIFO.

Others raise :class:`~hwsim.errors.NotAvailableError` naming what is modelled.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hwsim.arch import ArchConfig
from hwsim.engine.metrics import derive
from hwsim.errors import InputError, NotAvailableError
from hwsim.golden.positions import SamplePlan
from hwsim.scene import Scene
from hwsim.transfer import TransferFunction
from hwsim.volumes.volume import Volume
from models.arch.cube4_txn import Cube4Transaction
from models.arch.vizard2_txn import VizardTransaction
from models.arch.volumepro_txn import SlabTransaction
from models.arch.vp1000_txn import Vp1000Transaction
from models.datapath import Datapath
from models.functional import render_functional

__all__ = [
    "TRANSACTION_ORDERS",
    "TransactionResult",
    "has_transaction_model",
    "render_transaction",
    "transaction_model",
    "transaction_timing",
]

#: Processing orders with a transaction model, and the model's class.
TRANSACTION_ORDERS = {
    "slice-parallel": Cube4Transaction,
    "shear-warp": SlabTransaction,
    "shear-image": SlabTransaction,
    "ray": VizardTransaction,
}


#: Options only the models that read the frame's volume and termination steps take.
_SKIPPING_OPTIONS = ("volume", "transfer", "stopped", "datapath")
_READS_THE_FRAME = (Vp1000Transaction, VizardTransaction)


@dataclass
class TransactionResult:
    """Image (the functional rung's), samples, the event model's cycles and counters."""

    image: np.ndarray
    samples: int
    rays: int
    cycles: int
    counters: dict[str, Any] = field(default_factory=dict)
    derived: dict[str, Any] = field(default_factory=dict)


def has_transaction_model(arch: ArchConfig) -> bool:
    """Whether the transaction rung models ``arch`` (its processing order)."""
    return arch.order in TRANSACTION_ORDERS


def transaction_model(scene: Scene, arch: ArchConfig, plan: SamplePlan, **options: Any):
    """The event model of ``arch`` for one frame (not yet run).

    ``options`` go to the machine's model: ``pixel_fifo_depth`` (Cube-4 family),
    ``groups`` and ``steady_state`` (VolumePro family; refused elsewhere), ``volume``,
    ``transfer``, ``stopped``, ``datapath`` (VolumePro 1000 and VIZARD II; ignored by
    the others).
    """
    model = TRANSACTION_ORDERS.get(arch.order)
    if model is None:
        raise NotAvailableError(
            f"{arch.name} ({arch.order} order) has no transaction model yet",
            key="--arch",
            allowed="cube4, cube4-teramac, volumepro500, em-cube, volumepro1000, vizard2",
        )
    if model is SlabTransaction and (arch.early_termination or arch.space_leaping):
        model = Vp1000Transaction
    if options.get("steady_state") and not issubclass(model, SlabTransaction):
        raise InputError(
            f"{arch.name} ({arch.order} order) times single frames only",
            key="steady_state",
            allowed="a machine of order shear-warp, shear-image",
        )
    if not issubclass(model, SlabTransaction):
        options.pop("steady_state", None)
    if model not in _READS_THE_FRAME:
        options = {k: v for k, v in options.items() if k not in _SKIPPING_OPTIONS}
    return model(scene, arch, plan, **options)


def transaction_timing(scene: Scene, arch: ArchConfig, plan: SamplePlan, **options: Any):
    """Run only the event model of ``arch`` over ``plan`` (no image).

    A machine that skips beams (VolumePro 1000) or caches blocks (VIZARD II) needs
    ``volume=`` and ``transfer=`` (empty space, blocks) and,
    when its rays may stop early, renders the functional rung for their termination
    steps unless ``stopped=`` gives them.

    Returns
    -------
    models.arch.cube4_txn.TxnTiming
        Cycles and counters (:func:`transaction_model` for ``options``).
    """
    return transaction_model(scene, arch, plan, **options).run()


def render_transaction(
    scene: Scene,
    volume: Volume,
    transfer: TransferFunction,
    arch: ArchConfig,
    plan: SamplePlan,
    *,
    datapath: Datapath | None = None,
    progress: Callable[[int, int], None] | None = None,
    steady_state: bool = False,
) -> TransactionResult:
    """Render one frame: functional image, cycles from ``arch``'s event model.

    The event model is built first, so a machine without one (or a scene it refuses)
    fails before the image is computed; it runs after the image, whose per-ray
    termination steps a machine with early-ray-termination hardware needs.
    ``counters["transaction.timing_seconds"]`` and ``["transaction.image_seconds"]``
    split the wall time between the two parts.  ``steady_state`` (VolumePro family) also
    plays a second frame back to back: ``counters["frame.period_cycles"]``, as the cycle
    rung's rule 9.
    """
    model = transaction_model(
        scene,
        arch,
        plan,
        volume=volume,
        transfer=transfer,
        datapath=datapath,
        steady_state=steady_state,
    )
    start = time.perf_counter()
    image = render_functional(
        scene, volume, transfer, arch, plan, datapath=datapath, progress=progress
    )
    image_seconds = time.perf_counter() - start
    if isinstance(model, _READS_THE_FRAME):
        model.stopped = image.stopped  # the rays' termination steps (ERT hardware)
    timing = model.run()
    counters = dict(timing.counters)
    counters["transaction.image_seconds"] = image_seconds
    counters["functional.saturated"] = image.counters.get("functional.saturated", {})
    derived = derive(
        counters,
        cycles=timing.cycles,
        samples=image.samples,
        pipelines=arch.pipelines,
        clock_hz=arch.clock_hz,
    )
    return TransactionResult(
        image=image.image,
        samples=image.samples,
        rays=image.rays,
        cycles=timing.cycles,
        counters=counters,
        derived=derived,
    )
