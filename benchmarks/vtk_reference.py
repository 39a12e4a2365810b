"""VTK's CPU ray caster as the speed reference of the golden renderer.

Renders a volume with ``vtkFixedPointVolumeRayCastMapper`` into an offscreen render
window, with the transfer function, material, light, camera and sample distance of an
hwsim scene, and times it.  The VTK wheel from PyPI renders headless through EGL (Mesa)
here; ``VTK_DEFAULT_OPENGL_WINDOW`` is set to ``vtkEGLRenderWindow`` before VTK is
imported unless the caller already chose a window class (``vtkOSMesaRenderWindow`` is
the other headless choice).  VTK is imported on first use: importing this module needs
none (the run install has no ``bench`` extra), and :func:`vtk_missing` says whether it
is there.  The ray casting itself runs on the CPU, threaded by
``vtkMultiThreader``; OpenGL only draws the finished image as a texture.

Conventions (matching hwsim, see ``hwsim/spec/scene.py`` ``ViewSpec``):

* ``data_zyx`` has axis order ``(z, y, x)``; voxel centres sit at ``index * spacing``
  (VTK point data with origin 0), so the volume centre is ``(shape - 1) / 2 * spacing``.
* Parallel projection.  ``azimuth = elevation = 0`` looks along ``+z``; azimuth turns the
  view direction about ``y`` toward ``+x``, elevation tilts it toward ``+y``; the image
  up vector is ``+y`` at ``elevation = 0`` (in general ``d(view)/d(elevation)``).
* ``zoom = 1``: the bounding sphere of the volume box (half a voxel beyond the outer
  centres) fills the shorter image side.
* The light is directional, given in view space (x right, y up, z toward the viewer),
  pointing toward the light: a VTK camera light at that position.
* The returned image is float64 ``(height, width, 4)`` in ``[0, 1]``, row 0 at the *top*,
  colour composited over a black, fully transparent background (so premultiplied).
  It comes from the 8-bit framebuffer.

Ref: VTK ``Rendering/Volume/vtkFixedPointVolumeRayCastMapper`` (Lisa Avila, Kitware).
Early ray termination is built in and cannot be switched off: a ray stops once its
remaining opacity drops below ``0xff / 0x8000`` (:data:`VTK_EARLY_TERMINATION`).
"""

from __future__ import annotations

import os
import statistics
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = [
    "BENCH_EXTRA",
    "VTK_EARLY_TERMINATION",
    "VtkRayCaster",
    "render_vtk",
    "vtk_environment",
    "vtk_missing",
    "view_vectors",
]

#: Accumulated opacity at which the fixed-point mapper stops a ray: it stops when the
#: remaining opacity (15-bit fixed point) falls below 0xff.
VTK_EARLY_TERMINATION = 1.0 - 0xFF / 0x8000
#: How to install VTK: the ``bench`` extra (the run install has no VTK).
BENCH_EXTRA = "pip install -e .[bench]"


def _vtk():
    """VTK, imported on first use: this module's constants and camera geometry need none
    (the run install imports them without the ``bench`` extra)."""
    # The window class must be chosen before VTK is imported.
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import vtk

    return vtk


def vtk_missing() -> str | None:
    """None when VTK imports here, else why not in one line naming the extra to install."""
    try:
        _vtk()
    except ImportError as exc:
        if isinstance(exc, ModuleNotFoundError) and exc.name == "vtk":
            return f"needs vtk ({BENCH_EXTRA})"
        why = (str(exc).splitlines() or [type(exc).__name__])[0]
        return f"needs a working vtk ({BENCH_EXTRA}): {why}"
    return None


TransferPoint = tuple[float, float, float, float, float]


def view_vectors(azimuth: float, elevation: float) -> tuple[np.ndarray, np.ndarray]:
    """View direction and up vector, world ``(x, y, z)``, of hwsim's camera angles.

    Parameters
    ----------
    azimuth, elevation : float
        Degrees.  ``0, 0`` looks along ``+z``; azimuth turns toward ``+x`` about ``y``,
        elevation tilts toward ``+y``.

    Returns
    -------
    direction, up : ndarray
        Unit vectors; ``up`` is ``+y`` at zero elevation and stays perpendicular to
        ``direction`` (it is the derivative of the direction with respect to elevation,
        so it is defined at ``elevation = +-90`` too).
    """
    az, el = np.radians(azimuth), np.radians(elevation)
    direction = np.array([np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el)])
    up = np.array([-np.sin(az) * np.sin(el), np.cos(el), -np.cos(az) * np.sin(el)])
    return direction, up


def vtk_environment() -> dict[str, Any]:
    """What VTK renders with here: version, window class, OpenGL renderer, threads."""
    vtk = _vtk()
    window = vtk.vtkRenderWindow()
    window.SetOffScreenRendering(1)
    window.SetSize(8, 8)
    window.AddRenderer(vtk.vtkRenderer())
    window.Render()
    caps = window.ReportCapabilities() or ""
    gl_renderer = next(
        (
            line.split(":", 1)[1].strip()
            for line in caps.splitlines()
            if line.startswith("OpenGL renderer string")
        ),
        "",
    )
    info = {
        "vtk_version": vtk.vtkVersion.GetVTKVersion(),
        "window_class": window.GetClassName(),
        "opengl_renderer": gl_renderer,
        "threads": int(vtk.vtkMultiThreader.GetGlobalDefaultNumberOfThreads()),
    }
    window.Finalize()
    return info


class VtkRayCaster:
    """An offscreen ``vtkFixedPointVolumeRayCastMapper`` pipeline for one scene.

    Parameters
    ----------
    data_zyx : ndarray
        Scalar volume, axis order ``(z, y, x)``; any type the mapper accepts (uint8,
        int16, uint16, float32, ...).  Kept by reference, not copied.
    spacing_zyx : sequence of float
        World size of a voxel step along ``(z, y, x)``.
    tf_points : sequence of (value, r, g, b, a)
        Piecewise-linear transfer function; opacity per unit distance of one smallest
        voxel spacing (hwsim's definition), which is VTK's scalar opacity unit distance.
    width, height : int
        Image size in pixels.
    azimuth, elevation : float
        Camera angles in degrees (hwsim convention, see :func:`view_vectors`).
    shading : bool
        Phong shading with gradients from central differences (VTK's encoded normals).
    material : (ka, kd, ks, n)
        Ambient, diffuse, specular coefficients and specular power.
    sample_distance : float
        Distance between samples along a ray, world units.
    light_direction : (x, y, z)
        Toward the light, view space.
    light_intensity : float
        Light intensity.
    zoom : float
        1 = the volume's bounding sphere fills the shorter image side.
    threads : int, optional
        Ray-casting threads; default ``vtkMultiThreader``'s global default (the number
        of CPUs).
    """

    def __init__(
        self,
        data_zyx: np.ndarray,
        spacing_zyx: Sequence[float],
        tf_points: Sequence[TransferPoint],
        *,
        width: int,
        height: int,
        azimuth: float,
        elevation: float,
        shading: bool,
        material: tuple[float, float, float, float],
        sample_distance: float,
        light_direction: Sequence[float] = (-0.4, 0.5, 1.0),
        light_intensity: float = 1.0,
        zoom: float = 1.0,
        threads: int | None = None,
    ) -> None:
        if data_zyx.ndim != 3:
            raise ValueError(f"volume must be 3-D, got shape {data_zyx.shape}")
        vtk = _vtk()
        from vtk.util.numpy_support import numpy_to_vtk

        self._data = np.ascontiguousarray(data_zyx)  # VTK borrows this buffer
        nz, ny, nx = self._data.shape
        sz, sy, sx = (float(s) for s in spacing_zyx)

        image = vtk.vtkImageData()
        image.SetDimensions(nx, ny, nz)
        image.SetSpacing(sx, sy, sz)
        image.SetOrigin(0.0, 0.0, 0.0)
        scalars = numpy_to_vtk(self._data.reshape(-1), deep=False)
        scalars.SetName("scalars")
        image.GetPointData().SetScalars(scalars)
        self._scalars = scalars

        colour = vtk.vtkColorTransferFunction()
        opacity = vtk.vtkPiecewiseFunction()
        for value, r, g, b, a in tf_points:
            colour.AddRGBPoint(float(value), float(r), float(g), float(b))
            opacity.AddPoint(float(value), float(a))
        colour.ClampingOn()
        opacity.ClampingOn()

        ka, kd, ks, power = material
        prop = vtk.vtkVolumeProperty()
        prop.SetColor(colour)
        prop.SetScalarOpacity(opacity)
        prop.SetScalarOpacityUnitDistance(min(sx, sy, sz))
        prop.SetInterpolationTypeToLinear()
        prop.SetShade(1 if shading else 0)
        prop.SetAmbient(ka)
        prop.SetDiffuse(kd)
        prop.SetSpecular(ks)
        prop.SetSpecularPower(power)

        mapper = vtk.vtkFixedPointVolumeRayCastMapper()
        mapper.SetInputData(image)
        mapper.SetBlendModeToComposite()
        mapper.AutoAdjustSampleDistancesOff()
        mapper.LockSampleDistanceToInputSpacingOff()
        mapper.SetSampleDistance(float(sample_distance))
        mapper.SetInteractiveSampleDistance(float(sample_distance))
        mapper.SetImageSampleDistance(1.0)
        if threads is not None:
            mapper.SetNumberOfThreads(int(threads))
        mapper.SetMinimumImageSampleDistance(1.0)
        mapper.SetMaximumImageSampleDistance(1.0)

        volume = vtk.vtkVolume()
        volume.SetMapper(mapper)
        volume.SetProperty(prop)

        renderer = vtk.vtkRenderer()
        renderer.AddVolume(volume)
        renderer.SetBackground(0.0, 0.0, 0.0)
        renderer.SetBackgroundAlpha(0.0)
        light = vtk.vtkLight()
        light.SetLightTypeToCameraLight()
        light.SetPositional(False)
        light.SetFocalPoint(0.0, 0.0, 0.0)
        light.SetPosition(*(float(c) for c in light_direction))
        light.SetColor(1.0, 1.0, 1.0)
        light.SetIntensity(float(light_intensity))
        renderer.AddLight(light)

        window = vtk.vtkRenderWindow()
        window.SetOffScreenRendering(1)
        window.SetAlphaBitPlanes(1)
        window.SetMultiSamples(0)
        window.SetSize(int(width), int(height))
        window.AddRenderer(renderer)

        centre = (np.array([nx, ny, nz], dtype=np.float64) - 1.0) / 2.0 * [sx, sy, sz]
        radius = 0.5 * float(np.linalg.norm(np.array([nx * sx, ny * sy, nz * sz])))
        self._centre, self._radius = centre, radius
        camera = renderer.GetActiveCamera()
        camera.ParallelProjectionOn()
        self.renderer = renderer
        self.set_view(azimuth, elevation)
        scale = radius / zoom
        if width < height:
            scale *= height / width
        camera.SetParallelScale(scale)
        camera.SetClippingRange(2.0 * radius, 6.0 * radius)

        self.width, self.height = int(width), int(height)
        self.sample_distance = float(sample_distance)
        self.mapper, self.window, self.renderer = mapper, window, renderer
        self._keep = (image, colour, opacity, prop, volume, light)

    def set_view(self, azimuth: float, elevation: float) -> None:
        """Look at the volume from ``azimuth``, ``elevation`` (hwsim's convention)."""
        direction, up = view_vectors(azimuth, elevation)
        camera = self.renderer.GetActiveCamera()
        camera.SetFocalPoint(*self._centre)
        camera.SetPosition(*(self._centre - 4.0 * self._radius * direction))
        camera.SetViewUp(*up)

    @property
    def threads(self) -> int:
        """Threads the mapper casts rays with."""
        return int(self.mapper.GetNumberOfThreads())

    @property
    def window_class(self) -> str:
        """The concrete render window class (``vtkEGLRenderWindow`` here)."""
        return str(self.window.GetClassName())

    def render(self) -> float:
        """Render one frame; return its wall-clock time in seconds."""
        start = time.perf_counter()
        self.window.Render()
        return time.perf_counter() - start

    def image(self) -> np.ndarray:
        """The last frame as float64 RGBA ``(height, width, 4)``, row 0 at the top."""
        grab = _vtk().vtkWindowToImageFilter()
        grab.SetInput(self.window)
        grab.SetInputBufferTypeToRGBA()
        grab.ReadFrontBufferOff()
        grab.Update()
        out = grab.GetOutput()
        nx, ny, _ = out.GetDimensions()
        pixels = out.GetPointData().GetScalars()
        flat = np.frombuffer(memoryview(pixels), dtype=np.uint8).copy()
        rgba = flat.reshape(ny, nx, pixels.GetNumberOfComponents())[::-1]
        return rgba.astype(np.float64) / 255.0

    def close(self) -> None:
        """Release the OpenGL context."""
        self.window.Finalize()


def render_vtk(
    *args: Any,
    frames: int = 5,
    stats: dict[str, Any] | None = None,
    **options: Any,
) -> tuple[np.ndarray, float]:
    """Render ``data_zyx`` with VTK's CPU ray caster offscreen and time it.

    One warm-up frame (which also computes and encodes the gradients), then ``frames``
    timed frames.

    Parameters
    ----------
    *args, **options
        The volume, transfer function, view and lighting: :class:`VtkRayCaster`'s
        arguments.
    frames : int
        Timed frames after the warm-up; the median is returned.
    stats : dict, optional
        Filled with ``first_frame_seconds`` (warm-up, includes the gradient encoding),
        ``frame_seconds`` (every timed frame), ``frames``, ``threads``,
        ``sample_distance``, ``window_class`` and ``vtk_version``.

    Returns
    -------
    image : ndarray
        float64 RGBA ``(height, width, 4)``, row 0 at the top, premultiplied (over black).
    seconds_per_frame : float
        Median wall-clock time of the timed frames.
    """
    if frames < 1:
        raise ValueError(f"frames must be >= 1, got {frames}")
    caster = VtkRayCaster(*args, **options)
    try:
        first = caster.render()
        times = [caster.render() for _ in range(frames)]
        image = caster.image()
        if stats is not None:
            stats.update(
                first_frame_seconds=first,
                frame_seconds=times,
                frames=frames,
                threads=caster.threads,
                sample_distance=caster.sample_distance,
                window_class=caster.window_class,
                vtk_version=_vtk().vtkVersion.GetVTKVersion(),
            )
    finally:
        caster.close()
    return image, statistics.median(times)
