"""A Cube-4 cycle frame split into bands of rays gives the one-process frame bit for bit.

Each band reads only its rows of every slice (from the volume's parts: the head phantom
generated a box at a time, or a file read a box at a time) and routes them through a
band-sized datapath (models/machines/cube4/bands.py); the driver adds the bands' per-step
pipeline loads and times the frame.  The reference is the one-process frame, whose
slices come from the memory modules' host write and the slice FIFOs: image, samples,
cycles and every counter must be equal, for 1, 2, 3 and 5 bands, over views along every
principal axis, perspective, anisotropic voxels, every mode, crop and cut planes, early
termination, P = 3 and Teramac, and every data fault a band can reproduce; what it
cannot is refused.  (Dask itself: tests/system/test_split_frame_cli.py.)

The halo (``_band_origins`` proves it: one cell below and above a band's sample cells,
plus a shortened beam FIFO's reach above) has tests of its own: frames of a noise volume
where a band reading one wrong beam changes the image -- one fails at every band count
without the cell below, four without the reach -- and a sweep checking every read of
every band against its rows over views, shapes, P, faults and band cuts.

What the equality shows (docs/distributed-frames.md): the image's is evidence -- each
band computes its own halo, rows, skewed stream (``band_stream``) and band-sized routing,
where the one-process frame uses the host write and the whole slice.  The cycles' and the
timing counters' is a consistency check: both sides share ``Cube4Machine.frame``, which
times the whole frame from the whole plan in the driver (slice reads,
``cube4_pixel_pushes``, ``freezing_fifo``, ``cube4_latency``); the bands add only
per-step busy sums over disjoint rays, so the cycles equal by construction whenever the
bands partition the rays.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import rungs

from hwsim.core.errors import InputError
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.scene import (
    CropSpec,
    CutPlane,
    TransferSpec,
    VolumeSpec,
)
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import load_volume
from hwsim.volumes.parts import volume_parts
from models.backend import Backend
from models.cycle import render_cycle
from models.frame import frame_of
from models.machines.cube4.bands import BandSplit, _band_origins, split_rays, sweep_band
from models.machines.cube4.cycle import Cube4Machine, Faults

pytestmark = pytest.mark.model

HEAD = VolumeSpec(phantom="head", params=(("size", 28),))
THICK = VolumeSpec(phantom="head", params=(("size", 24), ("z_spacing", 1.5)))
MODULATED = TransferSpec(preset="ct", gradient_opacity=((100.0, 0.0), (1500.0, 1.0)))
CUT = (CutPlane(normal=(0.3, 0.2, 1.0), offset=1.0, thickness=6, falloff=3),)


def _scene(az=30, el=20, volume=HEAD, size=32, **kw):
    """:func:`rungs.scene_of` at this file's view: 32 pixels, zoom 1.3, the 28^3 head."""
    return rungs.scene_of(az, el, volume=volume, size=size, zoom=1.3, **kw)


CASES = {
    "oblique": ("cube4", _scene(), None),
    "along-z": ("cube4", _scene(az=0, el=0), None),
    "from-behind": ("cube4", _scene(az=200, el=-35), None),
    "x-principal": ("cube4", _scene(az=80, el=10), None),
    "y-principal": ("cube4", _scene(az=10, el=75), None),
    "perspective": ("cube4", _scene(az=25, el=15, projection="perspective"), None),
    "anisotropic": ("cube4", _scene(az=-60, el=30, volume=THICK), None),
    "mip": ("cube4", _scene(mode="mip"), None),
    "xray": ("cube4", _scene(mode="xray"), None),
    "iso": ("cube4", _scene(mode="iso", render={"iso_value": 300.0}), None),
    "unlit": ("cube4", _scene(render={"lighting": False}), None),
    "pre-classified": ("cube4", _scene(transfer=TransferSpec(preset="ct", order="pre")), None),
    "modulated-ert": (
        "cube4",
        _scene(transfer=MODULATED, render={"early_termination": 0.7}),
        None,
    ),
    "crop-cut": ("cube4", _scene(crop=CropSpec(y=(4, 15), invert=True), cut_planes=CUT), None),
    "P=3": ("cube4:3", _scene(az=40, el=-25), None),
    "teramac": ("cube4-teramac", _scene(az=-30, el=20), None),
    "stuck-module": ("cube4", _scene(), Faults(stuck_module=(1, 900))),
    "dropped-link": ("cube4", _scene(), Faults(dropped_link=2)),
    "short-beam-fifo": ("cube4", _scene(az=60, el=40), Faults(beam_fifo_adjust=-1)),
    "lost-handoff": ("cube4", _scene(), Faults(dropped_handoff=1)),
    "one-entry-pixel-fifo": ("cube4", _scene(), Faults(pixel_fifo_depth=1)),
}


def _arch(name: str):
    name, _, pipelines = name.partition(":")
    arch = resolve_arch(name)
    return dataclasses.replace(arch, pipelines=int(pipelines)) if pipelines else arch


def one_process(scene, arch, faults=None):
    volume = load_volume(scene.volume)
    frame = frame_of(scene, volume, resolve_transfer(scene.transfer, volume), arch)
    return render_cycle(frame, faults=faults)


def split_frame(scene, arch, bands: int, faults=None):
    """The frame in ``bands`` bands, each run as a worker runs it (no Dask)."""
    parts = volume_parts(scene.volume)
    volume = parts.volume()
    frame = frame_of(scene, volume, resolve_transfer(scene.transfer, volume), arch)
    split = BandSplit(frame, faults)
    groups = split.bands(bands)
    results = [sweep_band(frame, parts, rays, b, faults=faults) for b, rays in enumerate(groups)]
    return split.combine([sweep for sweep, _ in results]), [report for _, report in results]


def assert_same_frame(a, b):
    np.testing.assert_array_equal(a.image, b.image)
    assert (a.samples, a.rays, a.cycles) == (b.samples, b.rays, b.cycles)
    assert a.counters == b.counters


#: Every sample of every voxel value visible and lit, none near opaque: a band reading one
#: wrong voxel anywhere changes the image.
FAINT = TransferSpec(
    preset=None, points=((0.0, 0.2, 0.4, 0.6, 0.04), (4095.0, 1.0, 0.8, 0.5, 0.08))
)


@pytest.fixture(scope="module")
def noise(tmp_path_factory) -> VolumeSpec:
    """28^3 voxels of uniform noise in a ``.npy`` (read a box at a time, as any file): every
    voxel differs from its neighbours."""
    path = tmp_path_factory.mktemp("noise") / "noise.npy"
    np.save(path, np.random.default_rng(1).integers(0, 4096, size=(28, 28, 28)).astype(np.uint16))
    return VolumeSpec(path=str(path))


@pytest.mark.parametrize("case", list(CASES))
def test_a_frame_split_into_bands_is_the_one_process_frame(case):
    """The image (and the data-dependent counters: samples dropped after termination,
    transparent samples skipped) is evidence of the bands' halo, stream and routing; the
    cycles and timing counters are a consistency check: both sides share
    ``Cube4Machine.frame``, which times the whole plan (module docstring)."""
    name, scene, faults = CASES[case]
    arch = _arch(name)
    reference = one_process(scene, arch, faults)
    assert reference.samples > 0
    for bands in (1, 2, 3, 5):
        result, reports = split_frame(scene, arch, bands, faults)
        assert_same_frame(result, reference)
        assert sum(r.samples for r in reports) == reference.samples


def test_the_cycles_do_not_see_the_bands_the_image_does():
    """Why the cycles' equality is by construction (docs/distributed-frames.md): the
    driver times the frame from the whole plan, so combining one band of three leaves a
    parallel view's cycles as they are while the image loses two thirds of its rays."""
    name, scene, _ = CASES["oblique"]
    arch = _arch(name)
    reference = one_process(scene, arch)
    parts = volume_parts(scene.volume)
    volume = parts.volume()
    frame = frame_of(scene, volume, resolve_transfer(scene.transfer, volume), arch)
    split = BandSplit(frame)
    first = split.bands(3)[0]
    partial = split.combine([sweep_band(frame, parts, first, 0)[0]])
    assert partial.cycles == reference.cycles
    assert not np.array_equal(partial.image, reference.image)
    assert partial.samples < reference.samples


def test_each_band_reads_a_part_of_every_slice():
    """Two bands of a view along z read half the beams each plus two, never the whole
    volume; one band reads every beam the frame needs."""
    scene = _scene(az=0, el=0, volume=VolumeSpec(phantom="head", params=(("size", 48),)))
    arch = resolve_arch("cube4")
    (_, whole), (_, halves) = (split_frame(scene, arch, k) for k in (1, 2))
    assert whole[0].rows == 48 * 48
    assert len(halves) == 2
    for report in halves:
        # 26 beams of each of 48 slices: below, sample cells 0-23, their top cell's
        # second beam and a cell of halo; above, cells 23-47 (the cut falls just before
        # row 23's last ray) and a cell of halo.
        assert report.rows == 48 * (24 + 2)
        assert report.rays > 0 and report.peak_rss_bytes > 0


def test_bands_cut_the_rays_in_equal_samples_and_never_share_one():
    """The bands partition the rays: what makes the split frame's cycles the one-process
    frame's by construction (each band's busy sums cover disjoint rays)."""
    scene = _scene(az=35, el=25)
    volume = volume_parts(scene.volume).volume()
    frame = frame_of(scene, volume, resolve_transfer(scene.transfer, volume), resolve_arch("cube4"))
    plan = frame.plan
    groups = split_rays(plan, 3, BandSplit(frame).machine.a_ax)
    joined = np.concatenate(groups)
    assert np.array_equal(np.sort(joined), np.arange(plan.ray_ids.size))
    per_band = [int(np.sum(plan.j_hi[g] - plan.j_lo[g] + 1)) for g in groups]
    assert max(per_band) - min(per_band) < 0.05 * plan.samples


def test_more_bands_than_rays_leaves_bands_empty_and_the_frame_whole():
    scene = _scene(az=0, el=0, size=4, volume=VolumeSpec(phantom="head", params=(("size", 8),)))
    arch = resolve_arch("cube4")
    reference = one_process(scene, arch)
    result, reports = split_frame(scene, arch, 200)
    assert_same_frame(result, reference)
    assert any(r.rays == 0 for r in reports)


@pytest.mark.parametrize(
    ("faults", "key"),
    [
        (Faults(slice_fifo_adjust=-1), "faults.slice_fifo_adjust"),
        (Faults(beam_fifo_adjust=1), "faults.beam_fifo_adjust"),
    ],
)
def test_what_a_band_cannot_reproduce_is_refused(faults, key):
    scene = _scene()
    volume = volume_parts(scene.volume).volume()
    frame = frame_of(scene, volume, resolve_transfer(scene.transfer, volume), resolve_arch("cube4"))
    with pytest.raises(InputError, match=key.replace(".", r"\.")):
        BandSplit(frame, faults)
    with pytest.raises(InputError, match="--trace"):
        BandSplit(frame, None, trace=True)


@pytest.mark.parametrize("kind", ["npy", "nrrd"])
def test_a_file_read_a_box_at_a_time_gives_the_loaded_files_frame(kind, tmp_path):
    import nrrd

    from hwsim.volumes import make_phantom

    data = make_phantom("head", size=24, seed=2).data
    path = tmp_path / f"head.{kind}"
    if kind == "npy":
        np.save(path, data)
    else:
        nrrd.write(
            str(path), data, {"encoding": "raw", "spacings": [1.0, 1.0, 1.5]}, index_order="C"
        )
    scene = _scene(az=20, el=30, volume=VolumeSpec(path=str(path)))
    arch = resolve_arch("cube4")
    reference = one_process(scene, arch)
    result, _ = split_frame(scene, arch, 2)
    assert_same_frame(result, reference)


# ---------------------------------------------------------------- the halo (bands.py
# _band_origins proves it: one cell below a band's sample cells, one above, and above that
# the beam FIFO's reach when a fault shortens it)


@pytest.mark.parametrize("bands", [2, 3, 5, 8])
def test_the_halo_below_a_band_is_read_at_every_band_count(noise, bands):
    """``HALO_CELLS = 1`` is needed.  Along z every sample sits on integers: its gradient's
    down neighbour is cell ``c - 1`` at fraction 0, so it reads beam ``c - 1`` alone, one
    below the band's lowest sample cell, on every slice (no slice is taller to hide it).
    With ``HALO_CELLS = 0`` every band count's image differs (9, 68, 136 and 165 pixels)."""
    scene = _scene(az=0, el=0, volume=noise, transfer=FAINT, size=40)
    arch = resolve_arch("cube4")
    result, _ = split_frame(scene, arch, bands)
    assert_same_frame(result, one_process(scene, arch))


#: ``(arch, beam_fifo_adjust, elevation, bands)``, each looking along -x (azimuth 270).
SHORT_FIFOS = {
    "P=32-short": ("cube4:32", -1, 43, 12),
    "P=32-depth-0": ("cube4:32", -2, 43, 12),
    "P=4-short": ("cube4", -1, -35, 12),
    "P=4-depth-0": ("cube4", -8, -35, 12),
}


@pytest.mark.parametrize("case", list(SHORT_FIFOS))
def test_a_shortened_beam_fifo_reads_past_the_halo(noise, case):
    """The halo above grows by ``beam_fifo_reach``.  Azimuth 270 gives the beam axis z a
    shear of ``cos(270 deg) = -1.8e-16`` per slice: rows of samples at ``16 - 2^-49`` (cell
    15), whose gradient's up neighbour ``fl(p + 1.0) = 17.0`` is cell 17 at fraction 0;
    through a beam FIFO shortened by ``-C <= adjust <= -1`` (depth 0) that cell's corner
    ``(17, b)`` comes from beam 18 (19) in a beam's last group -- every column at P = 32,
    where C = 1 -- and 12 bands put such a row at a band's top on a slice as tall as the
    band.  Without the reach the image differs (P = 32: 12 and 165 pixels; P = 4: 2 and
    34); a FIFO of depth 0 also beats the halo of 2 the split had before (P = 32: 10
    pixels; P = 4: 2)."""
    name, adjust, el, bands = SHORT_FIFOS[case]
    scene = _scene(az=270, el=el, volume=noise, transfer=FAINT)
    arch, faults = _arch(name), Faults(beam_fifo_adjust=adjust)
    result, _ = split_frame(scene, arch, bands, faults)
    assert_same_frame(result, one_process(scene, arch, faults))


def _reads_outside_the_band(frame, rays: np.ndarray, faults: Faults | None) -> list:
    """Every read of band ``rays``'s sample pass whose corners come from beams the band
    does not hold (or, past the slice's edges, from a band that does not reach them):
    ``(step, slice, lowest beam, highest beam, band's first beam, band's last beam)``.

    Worked out from the datapath, not from the halo: the cells ``HardwareSource`` reads
    (its own cell whole, for the transparent-cell shortcut; with gradients the same cell
    on the slices ahead and behind and, on its slice, the cells of ``fl(p +- 1.0)``), and
    the beams each corner comes from (``tests/arch/test_slice_datapath_locality.py``:
    the beam-FIFO side ``c .. c + r``, the other ``c + 1``; a weight of 0 along the beam
    axis reads only the first, a weight of one only the second)."""
    plan = frame.plan.subset(np.isin(np.arange(frame.plan.ray_ids.size), rays))
    backend = Backend(dataclasses.replace(frame, plan=plan), compiled=False)
    m = Cube4Machine(backend, faults=faults)
    if not plan.ray_ids.size:
        return []
    a0, H = _band_origins(m)
    r = (m.C - 1 - m.faults.beam_fifo_adjust) // m.C  # restated: mutate bands.py, not this
    one = 1 << m.dp.interp.weight_bits
    outside = []
    for j, step in enumerate(plan.steps()):
        if not step.rays.size:
            continue
        q, p = m.slice_of(j), step.zyx[:, m.a_ax]
        own = m.cell(p)
        c = own[0]
        reads = [(q, c, c + max(1, r))]
        if m.need_slices:
            reads += [(k, c, c + max(1, r)) for k in (min(q + 1, m.n_kp - 1), max(q - 1, 0))]
            for cell, weight, _ in (m.cell(p + 1.0, own), m.cell(p - 1.0, own)):
                lo = np.where(weight == one, cell + 1, cell)
                hi = np.where(weight == 0, cell + r, cell + np.where(weight == one, 1, max(1, r)))
                reads.append((q, lo, hi))
        for k, lo, hi in reads:
            end = a0[k] + H - 1
            bad = (a0[k] < 0) | (np.maximum(lo, 0) < a0[k]) | (np.minimum(hi, m.n_a - 1) > end)
            if bad.any():
                outside.append((j, k, int(lo[bad].min()), int(hi[bad].max()), int(a0[k]), int(end)))
    return outside


def _halo_frames(kind: str):
    """``(label, frame, faults, bands)`` of the halo sweep.  ``rounding``: views along -x
    and +-y whose beam-axis shear is trigonometric noise (samples just below powers of
    two: the up neighbour two cells on), P = 4 and 32, every beam-FIFO reach.
    ``random``: a seeded draw of 40 views (a third perspective), volume sizes 10-30 with
    cubic or 1.5-thick voxels, P = 3, 4, 5, 32 and beam-FIFO adjustments 0, -1, -C,
    -(C + 1).  Bands: ``split_rays``' own for 3 and 12 bands, and runs of 24 thin bands
    merged at random cuts (the halo's proof holds for any set of rays)."""
    rng = np.random.default_rng(20)
    if kind == "rounding":
        views = [(270, el, 28, 1.0, False) for el in (-35, 0, 43)]
        views += [(-270, 20, 24, 1.0, False), (180, 90, 28, 1.0, False), (270, 10, 28, 1.5, False)]
        draws = [(*v, P, adj) for v in views for P in (4, 32) for adj in ("0", "-1", "-C-1")]
    else:
        draws = []
        for _ in range(40):
            view = (
                float(rng.uniform(-360, 360)),
                float(rng.uniform(-89, 89)),
                int(rng.integers(10, 31)),
                float(rng.choice([1.0, 1.5])),
                bool(rng.random() < 1 / 3),
            )
            draws.append(
                (*view, int(rng.choice([3, 4, 5, 32])), str(rng.choice(["0", "-1", "-C", "-C-1"])))
            )
    for az, el, size, z_spacing, perspective, P, adj in draws:
        params = (("size", size),) + ((("z_spacing", z_spacing),) if z_spacing != 1.0 else ())
        volume_spec = VolumeSpec(phantom="head", params=params)
        scene = _scene(
            az=az,
            el=el,
            volume=volume_spec,
            projection="perspective" if perspective else "parallel",
        )
        volume = volume_parts(volume_spec).volume()
        arch = dataclasses.replace(resolve_arch("cube4"), pipelines=P)
        frame = frame_of(scene, volume, resolve_transfer(scene.transfer, volume), arch)
        machine = BandSplit(frame).machine
        a_ax, C = machine.a_ax, machine.C
        adjust = {"0": 0, "-1": -1, "-C": -C, "-C-1": -C - 1}[adj]
        plan = frame.plan
        bands = [*split_rays(plan, 3, a_ax), *split_rays(plan, 12, a_ax)]
        thin = split_rays(plan, 24, a_ax)
        cuts = sorted(rng.choice(np.arange(1, 24), size=int(rng.integers(1, 6)), replace=False))
        runs = zip([0, *cuts], [*cuts, 24], strict=True)
        bands += [np.sort(np.concatenate(thin[i:j])) for i, j in runs]
        label = (
            f"az={az:.1f} el={el:.1f} {size}^3 z={z_spacing} persp={perspective} P={P} adj={adj}"
        )
        yield label, frame, Faults(beam_fifo_adjust=adjust), bands


@pytest.mark.parametrize("kind", ["rounding", "random"])
def test_every_cell_a_band_reads_lies_in_its_rows(kind):
    """The halo's property, checked read by read over a sweep of views, volume shapes,
    pipeline counts, beam-FIFO faults and band cuts (``_halo_frames``): no band's sample
    pass reads a corner from a beam its rows do not hold.  A halo one cell smaller
    (``HALO_CELLS = 0``), or one without the beam FIFO's reach, fails it."""
    failures = []
    for label, frame, faults, bands in _halo_frames(kind):
        for rays in bands:
            outside = _reads_outside_the_band(frame, rays, faults)
            if outside:
                failures.append((label, int(rays.size), outside[:2]))
    assert not failures, failures[:5]
