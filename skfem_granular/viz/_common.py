"""Helpers shared by :mod:`.frames` and :mod:`.animation` (private to the package).

Importing pyvista for off-screen rendering, the view (window size and
camera) that puts a box in the plot area, colour ranges, argument checks,
and the plotter's set-up and screenshot.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .layers import BAR, FIELDS, PAD, TITLE, VECTORS

GL_HELP = (
    "off-screen rendering needs the EGL and Mesa libraries (Debian/Ubuntu: apt-get "
    "install --no-install-recommends libegl1 libegl-mesa0 libgl1-mesa-dri); or set "
    "VTK_DEFAULT_OPENGL_WINDOW to vtkOSOpenGLRenderWindow (with OSMesa) or "
    "vtkXOpenGLRenderWindow (with an X server such as Xvfb)"
)
_window_checked = False


def require_pyvista():
    """Import pyvista for off-screen rendering, with a clear error when it cannot.

    On Linux, sets ``VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow`` and
    ``PYVISTA_OFF_SCREEN=true`` first unless they are set already.

    Returns
    -------
    module
        :mod:`pyvista`.

    Raises
    ------
    ImportError
        pyvista is not installed (``pip install 'skfem-granular[plot]'``).
    RuntimeError
        VTK cannot make the OpenGL window that ``VTK_DEFAULT_OPENGL_WINDOW``
        asks for (missing EGL or Mesa libraries).
    """
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
                f"their window at run time from 9.4 on): {GL_HELP}"
            )
        _window_checked = True
    return pyvista


@dataclass(frozen=True)
class View:
    """Window size and the parallel camera that puts ``box`` in the plot area."""

    box: tuple
    window_size: tuple
    origin: tuple
    scale: float

    @classmethod
    def fit(cls, box, window_size, colour_bar: bool, longest: int = 800) -> View:
        x0, y0, x1, y1 = (float(v) for v in box)
        if not (x1 > x0 and y1 > y0):
            raise ValueError(f"box = {box}: must be (x0, y0, x1, y1) with x1 > x0, y1 > y0")
        bar = BAR if colour_bar else 0
        bw, bh = x1 - x0, y1 - y0
        if window_size is None:
            s = max(bw, bh) / longest
            pw, ph = max(int(round(bw / s)), 160), max(int(round(bh / s)), 160)
            window_size = (pw + bar + 2 * PAD, ph + TITLE + 2 * PAD)
        W, H = (int(v) for v in window_size)
        pw, ph = W - bar - 2 * PAD, H - TITLE - 2 * PAD
        if pw < 16 or ph < 16:
            raise ValueError(f"window_size = {window_size}: too small for the plot")
        scale = max(bw / pw, bh / ph)
        # the box centre goes to the centre of the plot area
        c0, r0 = PAD + pw / 2, TITLE + PAD + ph / 2
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


def default_box(flow, margin: float = 0.02) -> tuple:
    """The flow mesh's bounding box and a ``margin`` (fraction of its longer side)."""
    x0, x1, y0, y1 = flow.bounds[:4]
    m = margin * max(x1 - x0, y1 - y0)
    return (x0 - m, y0 - m, x1 + m, y1 + m)


def in_box(points, box) -> np.ndarray:
    """Which of ``points`` lie in ``box`` (boolean mask)."""
    x, y = points[:, 0], points[:, 1]
    return (x >= box[0]) & (x <= box[2]) & (y >= box[1]) & (y <= box[3])


def field_range(flow, field: str, box) -> tuple[float, float]:
    """Colour range of ``field`` over the points in ``box``."""
    values = np.asarray(flow.point_data[field])[in_box(flow.points, box)]
    if values.size == 0:
        return (0.0, 0.0)
    if FIELDS[field][2]:
        m = float(np.max(np.abs(values)))
        return (-m, m)
    lo = 0.0 if field == "speed" else float(values.min())
    return (lo, float(values.max()))


def widen(clim) -> tuple[float, float]:
    """``clim`` as floats, widened about its value when it is empty."""
    lo, hi = (float(v) for v in clim)
    if hi > lo:
        return (lo, hi)
    m = max(abs(lo), abs(hi))
    return (lo - m, hi + m) if m > 0 else (lo - 1.0, hi + 1.0)


def read_vtu(pv, path, what: str):
    """``pv.read(path)``; a ``ValueError`` naming ``what`` when there is no such file."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{what} {str(path)!r}: not found")
    return pv.read(path)


def check_style(field, vectors, density):
    """Raise a ``ValueError`` for an unknown ``field`` or ``vectors``, a bad ``density``."""
    if field not in FIELDS:
        raise ValueError(f"field = {field!r}: must be one of {', '.join(map(repr, FIELDS))}")
    if vectors not in VECTORS:
        raise ValueError(f"vectors = {vectors!r}: must be None, 'glyphs' or 'streamlines'")
    if not (isinstance(density, int) and density >= 1):
        raise ValueError(f"density = {density!r}: must be an integer >= 1")


def default_title(field, vectors, time):
    """The title of a frame: field, vectors and time."""
    words = [field] + ([vectors] if vectors else [])
    text = ", ".join(words)
    return text if time is None else f"{text}   t = {time:.4g} s"


def z_offsets(view) -> tuple:
    """Small z offsets that keep overlays in front of the field."""
    L = max(view.box[2] - view.box[0], view.box[3] - view.box[1])
    return tuple(k * 1e-3 * L for k in (1, 2, 3, 4, 5))


def new_plotter(pv, view):
    """An off-screen plotter of the view's window size on a white background."""
    pl = pv.Plotter(off_screen=True, window_size=list(view.window_size))
    pl.set_background("white")
    return pl


def snapshot(pl, view) -> np.ndarray:
    """Render the plotter through the view's camera; the RGB pixels."""
    view.apply(pl)
    pl.suppress_rendering = False
    pl.render()
    img = pl.screenshot(None, return_img=True)
    return np.ascontiguousarray(img[:, :, :3])
