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
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

# field name -> (colormap, unit, symmetric colour range, colour of arrows and streamlines)
FIELDS = {
    "speed": ("viridis", "m/s", False, "white"),
    "pressure": ("coolwarm", "Pa", True, "black"),
    "vorticity": ("RdBu_r", "1/s", True, "black"),
    "mesh": (None, "", False, "black"),
}
VECTORS = (None, "glyphs", "streamlines")

CORE_FILL = "#c8c8c8"
CORE_EDGE = (0, 0, 0)
SHADOW_EDGE = (230, 120, 0)
WALL_FILL = "#8c8c8c"
MESH_EDGE = "#2b5d9b"

_PAD = 12  # pixels around the plot area
_TITLE = 36  # pixels above it for the title
_BAR = 150  # pixels right of it for the colour bar


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


def _grid(box, density: int, pv, flow):
    """Points of a regular grid in ``box`` that lie inside the flow mesh, sampled."""
    x0, y0, x1, y1 = box
    h = min(x1 - x0, y1 - y0) / density
    nx, ny = max(int((x1 - x0) / h), 1), max(int((y1 - y0) / h), 1)
    X, Y = np.meshgrid(
        x0 + (np.arange(nx) + 0.5) * (x1 - x0) / nx, y0 + (np.arange(ny) + 0.5) * (y1 - y0) / ny
    )
    cloud = pv.PolyData(np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)]))
    sampled = cloud.sample(flow)
    keep = np.asarray(sampled.point_data["vtkValidPointMask"]).astype(bool)
    return sampled.extract_points(keep, adjacent_cells=False), h


def _read(pv, path, what: str):
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{what} {str(path)!r}: not found")
    return pv.read(path)


def _draw(
    pl, pv, flow, particles, *, field, vectors, density, box, clim, arrow_scale, edges, title, z
):
    """Add the actors of one frame to the plotter ``pl``."""
    cmap, unit, _, ink = FIELDS[field]
    surface = _surface(pv, flow)
    if field == "mesh":
        # straight edges of the P2 triangles through their corner nodes
        cells = flow.cells_dict[pv.CellType.QUADRATIC_TRIANGLE][:, :3]
        faces = np.column_stack([np.full(len(cells), 3), cells]).ravel()
        linear = pv.PolyData(flow.points, faces=faces)
        pl.add_mesh(linear, color="white", lighting=False)
        pl.add_mesh(
            linear.translate((0, 0, z[0])),
            style="wireframe",
            color=MESH_EDGE,
            line_width=1,
            lighting=False,
        )
    else:
        actor = pl.add_mesh(
            surface,
            scalars=field,
            cmap=cmap,
            clim=clim,
            lighting=False,
            interpolate_before_map=True,
            show_scalar_bar=False,
        )
        if edges:
            cells = flow.cells_dict[pv.CellType.QUADRATIC_TRIANGLE][:, :3]
            faces = np.column_stack([np.full(len(cells), 3), cells]).ravel()
            pl.add_mesh(
                pv.PolyData(flow.points, faces=faces).translate((0, 0, z[0])),
                style="wireframe",
                color="white",
                opacity=0.35,
                line_width=1,
                lighting=False,
            )
        W, H = pl.window_size
        bar = pl.add_scalar_bar(
            mapper=actor.mapper,
            title=f"{field} ({unit})",
            n_labels=5,
            fmt="%.2e",
            vertical=True,
            position_x=(W - _BAR + 10) / W,
            position_y=(_PAD + 10) / H,
            width=(_BAR - 30) / W,
            height=min(0.8, 400 / H),
            color="black",
            title_font_size=14,
            label_font_size=12,
        )
        bar.SetVerticalTitleSeparation(6)
    if vectors == "glyphs":
        points, h = _grid(box, density, pv, flow)
        if points.n_points:
            u = np.asarray(points.point_data["velocity"], dtype=float)
            length = np.linalg.norm(u, axis=1)
            scale = arrow_scale
            if scale is None:
                scale = 0.9 * h / length.max() if length.max() > 0 else 0.0
            points.point_data["arrow_length"] = length * scale
            keep = length * scale > 0.05 * h
            if keep.any():
                points = points.extract_points(keep, adjacent_cells=False)
                arrow = pv.Arrow(tip_length=0.35, tip_radius=0.14, shaft_radius=0.04)
                glyphs = points.glyph(
                    orient="velocity", scale="arrow_length", factor=1.0, geom=arrow
                )
                pl.add_mesh(glyphs.translate((0, 0, z[1])), color=ink, lighting=False)
    elif vectors == "streamlines":
        lines = _streamlines(pv, surface, flow, box, density)
        if lines.n_points:
            pl.add_mesh(lines.translate((0, 0, z[1])), color=ink, line_width=1.2, lighting=False)
    if particles is not None:
        kind = np.asarray(particles.cell_data["kind"])
        walls = particles.extract_cells(np.flatnonzero(kind == 2))
        cores = particles.extract_cells(np.flatnonzero(kind == 1))
        shadows = particles.extract_cells(np.flatnonzero(kind == 0))
        if walls.n_cells:
            pl.add_mesh(walls, color=WALL_FILL, lighting=False)
        if cores.n_cells:
            pl.add_mesh(cores.translate((0, 0, z[2])), color=CORE_FILL, lighting=False)
        if shadows.n_cells:
            pl.add_mesh(
                shadows.translate((0, 0, z[3])),
                style="wireframe",
                color=SHADOW_EDGE,
                line_width=1.5,
                lighting=False,
            )
        if cores.n_cells:
            pl.add_mesh(
                cores.translate((0, 0, z[4])),
                style="wireframe",
                color=CORE_EDGE,
                line_width=2.5,
                lighting=False,
            )
    _mask(pl, pv, box, z[4] * 1.2)
    if title:
        pl.add_text(
            title, position=(_PAD, pl.window_size[1] - _TITLE + 6), font_size=12, color="black"
        )


def _streamlines(pv, surface, flow, box, density: int):
    """Streamlines about ``sep`` apart, ``sep`` = shorter side of ``box`` / ``density``.

    Traces from a grid of seeds (fastest first) and keeps the stretches of
    each line that stay clear of the lines kept before, on an occupancy grid
    of cells ``sep / 3`` (a greedy variant of Jobard and Lefer's method;
    VTK's vtkEvenlySpacedStreamlines2D crashed intermittently, VTK 9.7).
    """
    seeds, sep = _grid(box, density, pv, flow)
    if seeds.n_points == 0:
        return pv.PolyData()
    speed = np.linalg.norm(np.asarray(seeds.point_data["velocity"]), axis=1)
    if speed.max() == 0:
        return pv.PolyData()
    x0, y0, x1, y1 = box
    traced = surface.streamlines_from_source(
        seeds,
        vectors="velocity",
        integration_direction="both",
        step_unit="l",
        integrator_type=4,
        interpolator_type="cell",
        initial_step_length=sep / 3,
        max_steps=1000,
        max_length=2 * (x1 - x0 + y1 - y0),
        terminal_speed=1e-6 * speed.max(),
        compute_vorticity=False,
    )
    if traced.n_points == 0:
        return pv.PolyData()
    # each seed has a forward and a backward piece, both starting at the seed
    conn, pieces, k = np.asarray(traced.lines), {}, 0
    for seed in np.asarray(traced.cell_data["SeedIds"]):
        n = conn[k]
        pieces.setdefault(int(seed), []).append(conn[k + 1 : k + 1 + n])
        k += n + 1
    P = np.asarray(traced.points)
    c = sep / 3
    nx, ny = int((x1 - x0) / c) + 5, int((y1 - y0) / c) + 5
    cell = np.column_stack(
        [
            np.clip(((P[:, 0] - x0) / c).astype(int) + 2, 2, nx - 3),
            np.clip(((P[:, 1] - y0) / c).astype(int) + 2, 2, ny - 3),
        ]
    )
    owner = np.full((nx, ny), -1, dtype=np.int64)  # line that first entered a cell
    runs = []
    for line, seed in enumerate(sorted(pieces, key=lambda s: -speed[s])):
        i, j = cell[pieces[seed][0][0]]
        if np.any(owner[i - 2 : i + 3, j - 2 : j + 3] >= 0):
            continue  # the seed lies within about 2/3 sep of a line
        kept = []
        for ids in pieces[seed]:
            stop = len(ids)
            for n, p in enumerate(ids):
                i, j = cell[p]
                near = owner[i - 1 : i + 2, j - 1 : j + 2]
                if np.any((near >= 0) & (near != line)):
                    stop = n  # within about sep/3..sep of an earlier line
                    break
                if owner[i, j] < 0:
                    owner[i, j] = line
            kept.append(ids[:stop])
        ids = np.r_[kept[0][::-1], *(k[1:] for k in kept[1:])]
        if len(ids) >= 8:
            runs.append(ids)
        else:
            owner[owner == line] = -1
    if not runs:
        return pv.PolyData()
    lines = np.concatenate([np.r_[len(r), r] for r in runs])
    return pv.PolyData(P, lines=lines)


def _surface(pv, flow):
    """Linear triangles of the P2 mesh, each quadratic triangle subdivided twice."""
    from vtkmodules.vtkFiltersGeometry import vtkDataSetSurfaceFilter

    f = vtkDataSetSurfaceFilter()
    f.SetInputData(flow)
    f.SetNonlinearSubdivisionLevel(2)
    f.Update()
    return pv.wrap(f.GetOutput())


def _mask(pl, pv, box, z):
    """White bands that hide whatever lies outside ``box`` (walls, a zoomed mesh)."""
    x0, y0, x1, y1 = box
    L = 100 * max(x1 - x0, y1 - y0)
    bands = [
        (x0 - L, y0 - L, x0, y1 + L),
        (x1, y0 - L, x1 + L, y1 + L),
        (x0, y0 - L, x1, y0),
        (x0, y1, x1, y1 + L),
    ]
    points = np.array([[(a, b, z), (c, b, z), (c, d, z), (a, d, z)] for a, b, c, d in bands])
    faces = np.column_stack([np.full(4, 4), np.arange(16).reshape(4, 4)]).ravel()
    pl.add_mesh(pv.PolyData(points.reshape(-1, 3), faces=faces), color="white", lighting=False)


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


def read_pvd(path) -> list[tuple[float, Path]]:
    """``(time, file)`` pairs of a PVD collection, in file order.

    Examples
    --------
    >>> read_pvd("out/single_particle/flow.pvd")[:1]  # doctest: +SKIP
    [(0.0, PosixPath('out/single_particle/flow_00000.vtu'))]
    """
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except FileNotFoundError:
        raise ValueError(f"PVD file {str(path)!r}: not found") from None
    except ET.ParseError as exc:
        raise ValueError(f"PVD file {str(path)!r}: not valid XML ({exc})") from None
    return [
        (float(d.get("timestep", "nan")), path.parent / d.get("file")) for d in root.iter("DataSet")
    ]


def render_series(
    out_dir,
    path_animation,
    *,
    field: str = "speed",
    vectors: str | None = None,
    every: int = 1,
    fps: float = 10.0,
    density: int = 16,
    box=None,
    window_size=None,
    clim=None,
    edges: bool = False,
    outlines: bool = True,
) -> Path:
    """Render the frames of a run directory as an animated GIF or an MP4.

    Parameters
    ----------
    out_dir : str or Path
        A run's output directory with ``flow.pvd`` (and ``particles.pvd``).
    path_animation : str or Path
        ``*.gif`` (written with Pillow) or ``*.mp4`` (needs ``imageio`` and
        ``imageio-ffmpeg``).
    field, vectors, density, box, window_size, edges
        As for :func:`render_frame`; the box and the window are the same
        for all frames.
    every : int
        Use every this many frames of the series (the first one always).
    fps : float
        Frames per second of the animation.
    clim : (lo, hi), optional
        Colour range; default: the range over all frames used, so colours
        compare across frames. Arrows are scaled by the largest speed of
        all frames too.
    outlines : bool
        Draw the particles of ``particles.pvd`` (when it exists).

    Returns
    -------
    Path
        ``path_animation``.
    """
    _check(field, vectors, density)
    if not (isinstance(every, int) and every >= 1):
        raise ValueError(f"every = {every!r}: must be an integer >= 1")
    if not fps > 0:
        raise ValueError(f"fps = {fps!r}: must be > 0")
    path_animation = Path(path_animation)
    suffix = path_animation.suffix.lower()
    if suffix not in (".gif", ".mp4"):
        raise ValueError(f"path_animation {str(path_animation)!r}: must end in .gif or .mp4")
    out_dir = Path(out_dir)
    frames = read_pvd(out_dir / "flow.pvd")[::every]
    if not frames:
        raise ValueError(f"{str(out_dir / 'flow.pvd')!r}: no frames")
    outlines_by_time = {}
    if outlines and (out_dir / "particles.pvd").is_file():
        outlines_by_time = dict(read_pvd(out_dir / "particles.pvd"))
    pv = _pyvista()
    flows = [_read(pv, f, "flow frame") for _, f in frames]
    view = _View.fit(
        box if box is not None else _default_box(flows[0]), window_size, colour_bar=field != "mesh"
    )
    if field != "mesh" and clim is None:
        ranges = np.array([_field_range(f, field, view.box) for f in flows])
        clim = (ranges[:, 0].min(), ranges[:, 1].max())
    clim = None if field == "mesh" else _widen(clim)
    arrow_scale = None
    if vectors == "glyphs":
        umax = max(float(np.max(f.point_data["speed"], initial=0.0)) for f in flows)
        h = min(view.box[2] - view.box[0], view.box[3] - view.box[1]) / density
        arrow_scale = 0.9 * h / umax if umax > 0 else 0.0
    writer = _writer(path_animation, fps)
    z = _layers(view)
    pl = _plotter(pv, view)
    try:
        for (t, _), flow in zip(frames, flows, strict=True):
            pfile = outlines_by_time.get(t)
            particles = None if pfile is None else _read(pv, pfile, "particles frame")
            pl.suppress_rendering = True  # one render per frame, in _snapshot
            pl.clear()
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
                title=_title(field, vectors, t),
                z=z,
            )
            writer.append(_snapshot(pl, view))
    finally:
        pl.close()
    writer.close()
    return path_animation


class _GifWriter:
    """Collects frames and writes an animated GIF with Pillow on close."""

    def __init__(self, path: Path, fps: float):
        self.path, self.fps, self.frames = path, fps, []

    def append(self, image) -> None:
        from PIL import Image

        self.frames.append(Image.fromarray(image).quantize(colors=255, dither=0))

    def close(self) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        first, *rest = self.frames
        first.save(
            self.path,
            save_all=True,
            append_images=rest,
            loop=0,
            duration=int(round(1000 / self.fps)),
            disposal=1,
            optimize=False,
        )


class _Mp4Writer:
    def __init__(self, path: Path, fps: float):
        try:
            import imageio.v2 as imageio

            path.parent.mkdir(parents=True, exist_ok=True)
            self.writer = imageio.get_writer(path, fps=fps, macro_block_size=1)
        except (ImportError, ValueError) as exc:
            raise ImportError(
                f"MP4 output needs imageio and imageio-ffmpeg ({exc}); "
                "pip install imageio imageio-ffmpeg, or write a .gif"
            ) from exc

    def append(self, image) -> None:
        # H.264 in yuv420p needs an even width and height: pad with white
        h, w = image.shape[:2]
        pad = ((0, h % 2), (0, w % 2), (0, 0))
        self.writer.append_data(np.pad(image, pad, constant_values=255))

    def close(self) -> None:
        self.writer.close()


def _writer(path: Path, fps: float):
    return _GifWriter(path, fps) if path.suffix.lower() == ".gif" else _Mp4Writer(path, fps)
