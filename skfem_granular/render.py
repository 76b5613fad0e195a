"""Pictures of a run's output: VTU frames to PNG, PVD series to GIF or MP4.

Renders off-screen with pyvista (the ``plot`` extra:
``pip install 'skfem-granular[plot]'``); nothing here is imported by the rest
of the package. On Linux, unless the caller has set them, importing pyvista
through this module sets ``VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow`` and
``PYVISTA_OFF_SCREEN=true``, so no X display is needed; the machine needs the
EGL and Mesa libraries (Debian: ``apt-get install --no-install-recommends
libegl1 libegl-mesa0 libgl1-mesa-dri``). Set ``VTK_DEFAULT_OPENGL_WINDOW`` to
``vtkOSOpenGLRenderWindow`` (OSMesa) or ``vtkXOpenGLRenderWindow`` (X, e.g.
under Xvfb) to use those instead.

- :func:`render_frame`: one flow frame (``flow_*.vtu``) as the mesh or a
  scalar field (speed, pressure, vorticity) with a colour bar, optional
  velocity arrows or streamlines, particle outlines on top.
- :func:`render_series`: the frames of a run directory (``flow.pvd``,
  ``particles.pvd``) as an animated GIF (Pillow) or MP4 (imageio-ffmpeg),
  with one colour scale for all frames.

The picture shows the fluid box (``box``) at equal x and y scales; particle
cores are filled grey with a black outline, shadow (contact) outlines are
drawn in orange, DEM walls in grey.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .io import read_pvd  # noqa: F401  (re-exported: frames of a run)

# field name -> (colormap, unit, symmetric colour range, colour of arrows and streamlines)
from .render_layers import (  # noqa: F401  (re-exported names)
    _BAR,
    _PAD,
    _TITLE,
    CORE_EDGE,
    CORE_FILL,
    FIELDS,
    MESH_EDGE,
    SHADOW_EDGE,
    VECTORS,
    WALL_FILL,
    _draw,
    _grid,
    _mask,
    _streamlines,
    _surface,
)

_GL_HELP = (
    "off-screen rendering needs the EGL and Mesa libraries (Debian/Ubuntu: apt-get "
    "install --no-install-recommends libegl1 libegl-mesa0 libgl1-mesa-dri); or set "
    "VTK_DEFAULT_OPENGL_WINDOW to vtkOSOpenGLRenderWindow (with OSMesa) or "
    "vtkXOpenGLRenderWindow (with an X server such as Xvfb)"
)
_window_checked = False


def _pyvista():
    """Import pyvista for off-screen rendering, with a clear error when it cannot."""
    global _window_checked
    if sys.platform.startswith("linux"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
        os.environ.setdefault("PYVISTA_OFF_SCREEN", "true")
    try:
        import pyvista
    except ImportError as exc:
        raise ImportError(
            f"rendering needs pyvista ({exc}); install it with pip install 'skfem-granular[plot]'"
        ) from exc
    wanted = os.environ.get("VTK_DEFAULT_OPENGL_WINDOW")
    if wanted and not _window_checked:
        # When the requested window cannot be made (no libEGL, no Mesa EGL
        # vendor library, no DRI driver), VTK falls back to another one and
        # then crashes with a segmentation fault at the first render.
        import vtkmodules.vtkRenderingOpenGL2  # noqa: F401 (registers the OpenGL windows)
        from vtkmodules.vtkRenderingCore import vtkRenderWindow

        made = vtkRenderWindow().GetClassName()
        if made != wanted:
            from vtkmodules.vtkCommonCore import vtkVersion

            raise RuntimeError(
                f"VTK {vtkVersion.GetVTKVersion()} made a {made}, not the "
                f"VTK_DEFAULT_OPENGL_WINDOW={wanted} asked for (VTK wheels choose "
                f"their window at run time from 9.4 on): {_GL_HELP}"
            )
        _window_checked = True
    return pyvista


@dataclass(frozen=True)
class Picture:
    """A rendered frame.

    Attributes
    ----------
    path : Path or None
        Where the PNG was written (``None``: not written).
    image : ndarray
        The pixels, ``(height, width, 3)`` ``uint8``.
    box : (x0, y0, x1, y1)
        The part of the plane shown in the plot area.
    clim : (lo, hi) or None
        The colour range of the field (``None`` for ``field="mesh"``).
    """

    path: Path | None
    image: np.ndarray
    box: tuple
    clim: tuple | None
    _origin: tuple  # world coordinates of the window centre
    _scale: float  # world length per pixel

    def pixel(self, x: float, y: float) -> tuple[int, int]:
        """``(row, column)`` of the pixel showing the point ``(x, y)``."""
        h, w = self.image.shape[:2]
        col = w / 2 + (x - self._origin[0]) / self._scale
        row = h / 2 - (y - self._origin[1]) / self._scale
        return int(np.floor(row)), int(np.floor(col))


@dataclass(frozen=True)
class _View:
    """Window size and the parallel camera that puts ``box`` in the plot area."""

    box: tuple
    window_size: tuple
    origin: tuple
    scale: float

    @classmethod
    def fit(cls, box, window_size, colour_bar: bool, longest: int = 800) -> _View:
        x0, y0, x1, y1 = (float(v) for v in box)
        if not (x1 > x0 and y1 > y0):
            raise ValueError(f"box = {box}: must be (x0, y0, x1, y1) with x1 > x0, y1 > y0")
        bar = _BAR if colour_bar else 0
        bw, bh = x1 - x0, y1 - y0
        if window_size is None:
            s = max(bw, bh) / longest
            pw, ph = max(int(round(bw / s)), 160), max(int(round(bh / s)), 160)
            window_size = (pw + bar + 2 * _PAD, ph + _TITLE + 2 * _PAD)
        W, H = (int(v) for v in window_size)
        pw, ph = W - bar - 2 * _PAD, H - _TITLE - 2 * _PAD
        if pw < 16 or ph < 16:
            raise ValueError(f"window_size = {window_size}: too small for the plot")
        scale = max(bw / pw, bh / ph)
        # the box centre goes to the centre of the plot area
        c0, r0 = _PAD + pw / 2, _TITLE + _PAD + ph / 2
        origin = (
            (x0 + x1) / 2 + (W / 2 - c0) * scale,
            (y0 + y1) / 2 + (r0 - H / 2) * scale,
        )
        return cls((x0, y0, x1, y1), (W, H), origin, scale)

    def apply(self, plotter) -> None:
        fx, fy = self.origin
        d = 10 * max(self.box[2] - self.box[0], self.box[3] - self.box[1])
        plotter.camera_position = [(fx, fy, d), (fx, fy, 0.0), (0.0, 1.0, 0.0)]
        plotter.enable_parallel_projection()
        plotter.camera.parallel_scale = self.window_size[1] * self.scale / 2
        plotter.camera.clipping_range = (d / 100, 100 * d)


def _default_box(flow, margin: float = 0.02) -> tuple:
    x0, x1, y0, y1 = flow.bounds[:4]
    m = margin * max(x1 - x0, y1 - y0)
    return (x0 - m, y0 - m, x1 + m, y1 + m)


def _in_box(points, box) -> np.ndarray:
    x, y = points[:, 0], points[:, 1]
    return (x >= box[0]) & (x <= box[2]) & (y >= box[1]) & (y <= box[3])


def _field_range(flow, field: str, box) -> tuple[float, float]:
    """Colour range of ``field`` over the points in ``box``."""
    values = np.asarray(flow.point_data[field])[_in_box(flow.points, box)]
    if values.size == 0:
        return (0.0, 0.0)
    if FIELDS[field][2]:
        m = float(np.max(np.abs(values)))
        return (-m, m)
    lo = 0.0 if field == "speed" else float(values.min())
    return (lo, float(values.max()))


def _widen(clim) -> tuple[float, float]:
    lo, hi = (float(v) for v in clim)
    if hi > lo:
        return (lo, hi)
    m = max(abs(lo), abs(hi))
    return (lo - m, hi + m) if m > 0 else (lo - 1.0, hi + 1.0)


def _read(pv, path, what: str):
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{what} {str(path)!r}: not found")
    return pv.read(path)


def _check(field, vectors, density):
    if field not in FIELDS:
        raise ValueError(f"field = {field!r}: must be one of {', '.join(map(repr, FIELDS))}")
    if vectors not in VECTORS:
        raise ValueError(f"vectors = {vectors!r}: must be None, 'glyphs' or 'streamlines'")
    if not (isinstance(density, int) and density >= 1):
        raise ValueError(f"density = {density!r}: must be an integer >= 1")


def _title(field, vectors, time):
    words = [field] + ([vectors] if vectors else [])
    text = ", ".join(words)
    return text if time is None else f"{text}   t = {time:.4g} s"


def _plotter(pv, view):
    pl = pv.Plotter(off_screen=True, window_size=list(view.window_size))
    pl.set_background("white")
    return pl


def _snapshot(pl, view) -> np.ndarray:
    view.apply(pl)
    pl.suppress_rendering = False
    pl.render()
    img = pl.screenshot(None, return_img=True)
    return np.ascontiguousarray(img[:, :, :3])


def render_frame(
    flow_vtu,
    particles_vtu=None,
    path_png=None,
    *,
    field: str = "speed",
    vectors: str | None = None,
    density: int = 16,
    box=None,
    window_size=None,
    clim=None,
    edges: bool = False,
    time: float | None = None,
    title: str | None = None,
    arrow_scale: float | None = None,
) -> Picture:
    """Render one flow frame off-screen, optionally to a PNG file.

    Parameters
    ----------
    flow_vtu : str or Path
        A ``flow_*.vtu`` frame (quadratic triangles with point data
        ``velocity``, ``pressure``, ``speed``, ``vorticity``).
    particles_vtu : str or Path, optional
        The matching ``particles_*.vtu``; its outlines are drawn on top.
    path_png : str or Path, optional
        Write the picture here (PNG); ``None`` only returns it.
    field : {"speed", "pressure", "vorticity", "mesh"}
        A scalar field with its colour bar, or the triangles of the mesh.
    vectors : {None, "glyphs", "streamlines"}
        Velocity arrows on a regular grid (length proportional to the
        speed) or evenly spaced streamlines.
    density : int
        Arrows (or streamline spacings) across the shorter side of ``box``.
    box : (x0, y0, x1, y1), optional
        The part of the plane to show (zoom); default: the flow mesh and a
        2 % margin. Colour range and arrows are taken from this part.
    window_size : (width, height), optional
        Pixels; default: 800 along the longer side of ``box`` plus room for
        the title and the colour bar.
    clim : (lo, hi), optional
        Colour range; default: ``(0, max)`` for speed, ``(-m, m)`` with the
        largest magnitude ``m`` for pressure and vorticity.
    edges : bool
        Overlay the mesh edges on a scalar field.
    time : float, optional
        Shown in the default title.
    title : str, optional
        Replaces the default title (field, vectors and time); ``""`` for none.
    arrow_scale : float, optional
        Arrow length per unit speed (m per m/s); default: the longest arrow
        is 0.9 of the arrow spacing.

    Returns
    -------
    Picture
        The pixels, the path written and the pixel of a point
        (:meth:`Picture.pixel`).

    Raises
    ------
    ImportError
        pyvista is not installed (``pip install 'skfem-granular[plot]'``).
    ValueError
        Bad arguments or missing files.
    """
    _check(field, vectors, density)
    if path_png is not None:
        path_png = Path(path_png)
        if path_png.suffix.lower() != ".png":
            raise ValueError(f"path_png {str(path_png)!r}: must end in .png")
    pv = _pyvista()
    flow = _read(pv, flow_vtu, "flow_vtu")
    particles = None if particles_vtu is None else _read(pv, particles_vtu, "particles_vtu")
    missing = {"velocity", field if field != "mesh" else "velocity"} - set(flow.point_data)
    if missing:
        raise ValueError(f"flow_vtu {str(flow_vtu)!r}: no point data {sorted(missing)}")
    view = _View.fit(
        box if box is not None else _default_box(flow), window_size, colour_bar=field != "mesh"
    )
    if field != "mesh":
        clim = _widen(clim if clim is not None else _field_range(flow, field, view.box))
    else:
        clim = None
    z = _layers(view)
    pl = _plotter(pv, view)
    try:
        _draw(
            pl,
            pv,
            flow,
            particles,
            field=field,
            vectors=vectors,
            density=density,
            box=view.box,
            clim=clim,
            arrow_scale=arrow_scale,
            edges=edges,
            title=_title(field, vectors, time) if title is None else title,
            z=z,
        )
        image = _snapshot(pl, view)
    finally:
        pl.close()
    if path_png is not None:
        _save_png(image, path_png)
    return Picture(path_png, image, view.box, clim, view.origin, view.scale)


def _layers(view) -> tuple:
    """Small z offsets that keep overlays in front of the field."""
    L = max(view.box[2] - view.box[0], view.box[3] - view.box[1])
    return tuple(k * 1e-3 * L for k in (1, 2, 3, 4, 5))


def _save_png(image, path: Path) -> None:
    from PIL import Image

    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(image).save(path)


def __getattr__(name):
    # render_series lives in skfem_granular.animation (imports this module)
    if name == "render_series":
        from .animation import render_series

        return render_series
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
