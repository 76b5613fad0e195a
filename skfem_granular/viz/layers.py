"""Drawing layers of a rendered frame: field, mesh, arrows, streamlines, outlines.

:func:`draw` adds the actors of one frame to a pyvista plotter (pyvista
objects in, pyvista actors out); the colours and the pixel sizes of the
layout that every picture shares are defined here.
"""

from __future__ import annotations

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

PAD = 12  # pixels around the plot area
TITLE = 36  # pixels above it for the title
BAR = 150  # pixels right of it for the colour bar


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


def draw(
    pl, pv, flow, particles, *, field, vectors, density, box, clim, arrow_scale, edges, title, z
):
    """Add the actors of one frame to the plotter ``pl``.

    ``z`` holds five small increasing z offsets (mesh edges, vectors,
    particle cores, shadow outlines, core outlines) that keep the overlays
    in front of the field.
    """
    ink = FIELDS[field][3]
    surface = _surface(pv, flow)
    if field == "mesh":
        _draw_mesh(pl, pv, flow, z[0])
    else:
        _draw_field(pl, pv, flow, surface, field, clim, edges, z[0])
    if vectors == "glyphs":
        _draw_glyphs(pl, pv, flow, box, density, arrow_scale, ink, z[1])
    elif vectors == "streamlines":
        lines = _streamlines(pv, surface, flow, box, density)
        if lines.n_points:
            pl.add_mesh(lines.translate((0, 0, z[1])), color=ink, line_width=1.2, lighting=False)
    if particles is not None:
        _draw_particles(pl, particles, z)
    _mask(pl, pv, box, z[4] * 1.2)
    if title:
        pl.add_text(
            title, position=(PAD, pl.window_size[1] - TITLE + 6), font_size=12, color="black"
        )


def _linear_edges(pv, flow):
    """The straight edges of the P2 triangles through their corner nodes, as PolyData."""
    cells = flow.cells_dict[pv.CellType.QUADRATIC_TRIANGLE][:, :3]
    faces = np.column_stack([np.full(len(cells), 3), cells]).ravel()
    return pv.PolyData(flow.points, faces=faces)


def _draw_mesh(pl, pv, flow, z_edges: float):
    """The mesh alone: white triangles with blue edges."""
    linear = _linear_edges(pv, flow)
    pl.add_mesh(linear, color="white", lighting=False)
    pl.add_mesh(
        linear.translate((0, 0, z_edges)),
        style="wireframe",
        color=MESH_EDGE,
        line_width=1,
        lighting=False,
    )


def _draw_field(pl, pv, flow, surface, field: str, clim, edges: bool, z_edges: float):
    """The coloured field, the mesh edges over it if asked, and its colour bar."""
    cmap, unit = FIELDS[field][:2]
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
        pl.add_mesh(
            _linear_edges(pv, flow).translate((0, 0, z_edges)),
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
        position_x=(W - BAR + 10) / W,
        position_y=(PAD + 10) / H,
        width=(BAR - 30) / W,
        height=min(0.8, 400 / H),
        color="black",
        title_font_size=14,
        label_font_size=12,
    )
    bar.SetVerticalTitleSeparation(6)


def _draw_glyphs(pl, pv, flow, box, density: int, arrow_scale, ink, z: float):
    """Velocity arrows on a regular grid (the shortest, below 5 % of its pitch, left out)."""
    points, h = _grid(box, density, pv, flow)
    if not points.n_points:
        return
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
        glyphs = points.glyph(orient="velocity", scale="arrow_length", factor=1.0, geom=arrow)
        pl.add_mesh(glyphs.translate((0, 0, z)), color=ink, lighting=False)


def _draw_particles(pl, particles, z):
    """Walls, filled cores, shadow outlines and core outlines, in that order."""
    kind = np.asarray(particles.cell_data["kind"])
    walls = particles.extract_cells(np.flatnonzero(kind == 2))
    cores = particles.extract_cells(np.flatnonzero(kind == 1))
    shadows = particles.extract_cells(np.flatnonzero(kind == 0))
    if walls.n_cells:
        pl.add_mesh(walls, color=WALL_FILL, lighting=False)
    if cores.n_cells:
        pl.add_mesh(cores.translate((0, 0, z[2])), color=CORE_FILL, lighting=False)
    for cells, z_k, colour, width in ((shadows, z[3], SHADOW_EDGE, 1.5),
                                      (cores, z[4], CORE_EDGE, 2.5)):
        if cells.n_cells:  # outlines: shadows thin and orange, cores thick and black
            pl.add_mesh(cells.translate((0, 0, z_k)), style="wireframe", color=colour,
                        line_width=width, lighting=False)


def _clear_runs(pieces: dict, cell: np.ndarray, speed: np.ndarray, shape: tuple) -> list:
    """The stretches of the traced lines (``pieces``: per seed, its backward and forward
    point ids) that stay clear of the lines kept before, fastest seed first, on the
    occupancy grid of ``shape`` whose cell holds each point (``cell``)."""
    owner = np.full(shape, -1, dtype=np.int64)  # line that first entered a cell
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
    return runs


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
    conn, k = np.asarray(traced.lines), 0
    pieces: dict[int, list[np.ndarray]] = {}
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
    runs = _clear_runs(pieces, cell, speed, (nx, ny))
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
