"""One picture of a run's output: a VTU flow frame (and its particles) as a PNG.

:func:`render_frame` draws the fluid box at equal x and y scales, as the mesh
or a scalar field (speed, pressure, vorticity) with a colour bar, optional
velocity arrows or streamlines, particle outlines on top; it returns a
:class:`Picture`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..io import atomic_write, check_writable
from ._common import (
    View,
    check_style,
    default_box,
    default_title,
    field_range,
    new_plotter,
    read_vtu,
    require_pyvista,
    snapshot,
    widen,
    z_offsets,
)
from .layers import draw


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
        Write the picture here (PNG, under a temporary name renamed when
        complete: a failure leaves an earlier file as it was); ``None`` only
        returns it.
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
        Bad arguments, missing files, or a ``path_png`` that cannot be written
        (checked before rendering).
    OSError
        Writing the PNG failed (a full disk): an earlier file stays as it was.
    """
    check_style(field, vectors, density)
    if path_png is not None:
        path_png = Path(path_png)
        if path_png.suffix.lower() != ".png":
            raise ValueError(f"path_png {str(path_png)!r}: must end in .png")
        check_writable(path_png)  # before any rendering
    pv = require_pyvista()
    flow = read_vtu(pv, flow_vtu, "flow_vtu")
    particles = None if particles_vtu is None else read_vtu(pv, particles_vtu, "particles_vtu")
    missing = {"velocity", field if field != "mesh" else "velocity"} - set(flow.point_data)
    if missing:
        raise ValueError(f"flow_vtu {str(flow_vtu)!r}: no point data {sorted(missing)}")
    view = View.fit(
        box if box is not None else default_box(flow), window_size, colour_bar=field != "mesh"
    )
    if field != "mesh":
        clim = widen(clim if clim is not None else field_range(flow, field, view.box))
    else:
        clim = None
    z = z_offsets(view)
    pl = new_plotter(pv, view)
    try:
        draw(
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
            title=default_title(field, vectors, time) if title is None else title,
            z=z,
        )
        image = snapshot(pl, view)
    finally:
        pl.close()
    if path_png is not None:
        _save_png(image, path_png)
    return Picture(path_png, image, view.box, clim, view.origin, view.scale)


def _save_png(image, path: Path) -> None:
    """Write ``image`` as a PNG at a temporary name and rename it onto ``path``."""
    from PIL import Image

    atomic_write(path, lambda tmp: Image.fromarray(image).save(tmp, format="PNG"))
