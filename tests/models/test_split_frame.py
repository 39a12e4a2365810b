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

from hwsim.errors import InputError
from hwsim.fidelity import resolve_arch
from hwsim.scene import CropSpec, CutPlane, RenderSpec, Scene, TransferSpec, ViewSpec, VolumeSpec
from hwsim.transfer import resolve_transfer
from hwsim.volumes import load_volume
from hwsim.volumes.parts import volume_parts
from models.cycle import render_cycle
from models.frame import frame_of
from models.machines.cube4.bands import BandSplit, split_rays, sweep_band
from models.machines.cube4.cycle import Faults

pytestmark = pytest.mark.model

HEAD = VolumeSpec(phantom="head", params=(("size", 28),))
THICK = VolumeSpec(phantom="head", params=(("size", 24), ("z_spacing", 1.5)))
MODULATED = TransferSpec(preset="ct", gradient_opacity=((100.0, 0.0), (1500.0, 1.0)))
CUT = (CutPlane(normal=(0.3, 0.2, 1.0), offset=1.0, thickness=6, falloff=3),)


def _scene(az=30, el=20, volume=HEAD, size=32, transfer=None, projection="parallel", **kw):
    return Scene(
        volume=volume,
        transfer=transfer or TransferSpec(preset="ct"),
        view=ViewSpec(
            azimuth=az, elevation=el, width=size, height=size, zoom=1.3, projection=projection
        ),
        render=RenderSpec(**{"mode": "composite", **kw.pop("render", {})}),
        **kw,
    )


CASES = {
    "oblique": ("cube4", _scene(), None),
    "along-z": ("cube4", _scene(az=0, el=0), None),
    "from-behind": ("cube4", _scene(az=200, el=-35), None),
    "x-principal": ("cube4", _scene(az=80, el=10), None),
    "y-principal": ("cube4", _scene(az=10, el=75), None),
    "perspective": ("cube4", _scene(az=25, el=15, projection="perspective"), None),
    "anisotropic": ("cube4", _scene(az=-60, el=30, volume=THICK), None),
    "mip": ("cube4", _scene(render={"mode": "mip"}), None),
    "xray": ("cube4", _scene(render={"mode": "xray"}), None),
    "iso": ("cube4", _scene(render={"mode": "iso", "iso_value": 300.0}), None),
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
    """Two bands of a view along z read about half the beams each (plus the halo), never
    the whole volume; one band reads every beam the frame needs."""
    scene = _scene(az=0, el=0, volume=VolumeSpec(phantom="head", params=(("size", 48),)))
    arch = resolve_arch("cube4")
    (_, whole), (_, halves) = (split_frame(scene, arch, k) for k in (1, 2))
    assert len(halves) == 2
    for report in halves:
        assert report.rows < 0.62 * whole[0].rows  # half the beams + 2 x 2 of halo
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
