"""Particle groups: a fine body-fitted mesh inside a circle, graded circles outside.

The fine region is the disk around the bulk of the particles, clipped by the
domain: a full circle inside the domain, a circular sector or segment when
the circle is cut by walls (the paper's Fig. 13 places the centre on the
bottom wall). Its outline, the *transition*, is a polygon with edge length
about ``h``; its nodes carry the graded circles outside (Eq. 4 with
``r0 = radius``) and are shared by both regions, so the mesh is conforming
along the transition (no hanging nodes). The fine part is a quality
constrained Delaunay mesh with the size bound of :func:`meshing.uniform_mesh`.
"""

from __future__ import annotations

import numpy as np
import skfem
from numpy.typing import NDArray

from .cleanup import truncate, wall_nodes
from .geometry import centroid, clip_convex, edge_distance, inside
from .graded import ring_nodes, rings, sizing_of
from .inputs import check_rounds, check_sigma, prepare, size_cap
from .pslg import Layout, fixed_point, triangulate
from .registry import builds
from .repair import build
from .skfem_mesh import to_body_fitted
from .uniform import AREA_FACTOR, MIN_ANGLE, split_walls
from .value import BodyFittedMesh, Recipe

GROUP_SIGMA = 1.2
"""Default growth factor of the element size per circle outside a group (the
paper's value for particle groups; Eq. 4 with ``r0 = radius`` would give
``1 + h / radius``, close to 1 for large groups)."""

MIN_CROSSING = 60.0
"""Smallest accepted angle (degrees) between the group circle and a wall it crosses."""


def transition_outline(D: NDArray[np.float64], center: NDArray[np.float64], radius: float,
                       h: float) -> tuple[NDArray, NDArray, NDArray]:
    """Circle polygon (edge about ``h``) clipped by the domain.

    Returns ``(C, T, arc)``: the full circle polygon ``(2, n)``, the fine
    region's outline ``T`` ``(2, m)`` (ccw, convex) and a boolean ``(m,)``
    telling which edges of ``T`` lie on the circle (the others on walls).
    """
    n = max(16, int(np.ceil(2.0 * np.pi * radius / h)))
    phi = 2.0 * np.pi * np.arange(n) / n
    C = center[:, None] + radius * np.vstack([np.cos(phi), np.sin(phi)])
    T = clip_convex(C, D)
    tol = 1e-9 * radius
    on_wall = np.abs(edge_distance(D, T)[0]) <= tol
    # drop circle vertices crowding an intersection point on a wall
    gap_next = np.hypot(*(np.roll(T, -1, axis=1) - T))
    gap_prev = np.roll(gap_next, 1)
    crowd = ~on_wall & (((gap_next < 0.3 * h) & np.roll(on_wall, -1))
                        | ((gap_prev < 0.3 * h) & np.roll(on_wall, 1)))
    T = T[:, ~crowd]
    mid = 0.5 * (T + np.roll(T, -1, axis=1))
    arc = np.abs(edge_distance(D, mid)[0]) > tol
    return C, T, arc


def group_mesh(domain: object = (0.0, 0.0, 3e-3, 11e-3), particles: object = (),
               h: float | None = None, sigma: float | None = None,
               delta_l: float | None = None, *, center: object = None,
               radius: float | None = None,
               relax_rounds: int = 4) -> skfem.MeshTri:
    """Mesh of a particle group: fine inside a circle (or sector), graded outside.

    Parameters
    ----------
    domain, particles, delta_l
        As in :func:`meshing.graded_mesh` (at least one particle).
    h
        Edge length of the fine region and the transition polygon,
        ``0 < h < radius``; default the particles' mean outline edge length.
    sigma
        Growth factor of the element size from one graded circle to the next,
        ``1 < sigma <= 2``; default :data:`GROUP_SIGMA` = 1.2 (the paper's
        value for groups). The first circle lies ``h`` outside the
        transition; circle ``i`` is ``h sigma**i`` from the next and carries
        as many nodes as keep its node spacing equal to that (the node count
        drops as the circles coarsen). ``sigma = 1 + h / radius`` gives
        Eq. 4 with ``r0 = radius`` (every circle with the transition's node
        count).
    center
        ``(x, y)`` centre of the circle, inside the domain or on its outline;
        default the mean of the particle centroids. On a wall the fine
        region becomes a half disk (a sector in a corner).
    radius
        Circle radius; default the largest distance of a particle vertex from
        ``center`` plus ``2 h``, adapted by :func:`fit_circle` so that the
        circle crosses walls at 60 degrees or more. Must leave at least ``h``
        between every particle and the circle.
    relax_rounds
        As in :func:`meshing.graded_mesh`; relaxation moves graded nodes only.

    Returns
    -------
    skfem.MeshTri
        Named boundaries as in :func:`meshing.graded_mesh`; ``subdomains``
        ``"fine"`` and ``"graded"`` (element indices). The transition edges
        are the facets shared by a fine and a graded element.
        ``meshing.build("group", domain, particles, ...)`` returns the same
        mesh as a :class:`meshing.BodyFittedMesh`.
    """
    return build_group(domain, particles, h=h, sigma=sigma, delta_l=delta_l, center=center,
                       radius=radius, relax_rounds=relax_rounds).mesh


@builds("group")
def build_group(domain: object, particles: object, *, h: float | None = None,
                sigma: float | None = None, delta_l: float | None = None,
                center: object = None, radius: float | None = None,
                relax_rounds: int = 4) -> BodyFittedMesh:
    """:func:`group_mesh` as a :class:`~meshing.value.BodyFittedMesh`.

    What :func:`meshing.build` calls for ``kind="group"``; the arguments and
    the mesh are those of :func:`group_mesh`.
    """
    sigma = check_sigma(sigma)
    check_rounds(relax_rounds)
    D, names, outlines = prepare(domain, particles, delta_l)
    if not outlines:
        raise ValueError("particles: group_mesh needs at least one particle")
    allv = np.hstack(outlines)
    if h is None:
        h = float(np.mean(np.hstack([np.hypot(*(np.roll(P, -1, axis=1) - P))
                                     for P in outlines])))
    h = _positive(h, "h")
    c = _center(center, D, outlines)
    radius_arg = radius
    if radius is not None:
        radius = _positive(radius, "radius")
        reach = float(np.max(np.hypot(*(allv - c[:, None]))))
        if radius < reach + h:
            raise ValueError(f"radius: must be >= {reach + h:.6g} (farthest particle vertex "
                             f"from center plus h), got {radius:.6g}")
    c, radius = fit_circle(D, allv, c, radius, h, free_center=center is None)
    C, T, arc = transition_outline(D, c, radius, h)
    fine = _fine_layout(T, outlines, h)
    tri = triangulate(fine, f"q{fixed_point(MIN_ANGLE)}Ya"
                            f"{fixed_point(AREA_FACTOR * np.sqrt(3.0) / 4.0 * h * h)}")
    fixed, fixed_wall, fixed_wall_edge, segs = _fine_nodes(D, T, arc, fine, tri)
    r_max = float(np.max(np.hypot(*(D - c[:, None]))))
    ring = rings(C, GROUP_SIGMA if sigma is None else sigma, r_max, center=c,
                 h_max=max(size_cap(D), h))
    sizing = sizing_of([ring])
    free, proj, proj_edge = truncate(D, [T], ring_nodes(C, ring), sizing)
    wall, wall_edge = wall_nodes(D, proj, proj_edge, sizing, fixed_wall, fixed_wall_edge)
    layout = Layout(domain=D, edge_names=names, particles=outlines, wall=wall,
                    wall_edge=wall_edge, free=free, fixed=fixed, fixed_segments=segs,
                    n_wall_fixed=fixed_wall.shape[1])
    layout, tri = build(layout, sizing, [T], relax_rounds)
    in_fine = _in_region(tri, T, c, radius, C.shape[1])
    recipe = Recipe("group", domain, tuple(outlines),
                    dict(h=h, sigma=sigma, delta_l=delta_l, center=center, radius=radius_arg,
                         relax_rounds=relax_rounds))
    return to_body_fitted(tri, layout, recipe, {"fine": in_fine, "graded": ~in_fine})


def fit_circle(D: NDArray[np.float64], allv: NDArray[np.float64], c: NDArray[np.float64],
               radius: float | None, h: float, free_center: bool) -> tuple[NDArray, float]:
    """Centre and radius of the group circle, avoiding shallow wall crossings.

    Where the circle meets a wall at less than :data:`MIN_CROSSING` degrees,
    or passes closer than ``h`` to it, the fine region would end in a thin
    wedge or sliver. A default circle (``radius=None``) then, in this order:
    shrinks to keep ``h`` from that wall if the particles allow it; moves its
    (default) centre onto the wall, which makes the fine region a half disk
    or sector crossed at right angles (the paper's Fig. 13); grows until it
    crosses at :data:`MIN_CROSSING` degrees. A given radius that crosses
    shallowly raises ValueError.
    """
    user_radius = radius is not None
    E = np.roll(D, -1, axis=1) - D
    n = np.vstack([-E[1], E[0]]) / np.hypot(*E)          # inward normals (ccw)
    cos_min = float(np.cos(np.radians(MIN_CROSSING)))
    moved = np.zeros(D.shape[1], dtype=bool)
    R = None if radius is None else float(radius)
    grown = False
    for _ in range(8 * D.shape[1]):
        reach = float(np.max(np.hypot(*(allv - c[:, None]))))
        if R is None:
            R = reach + 2.0 * h
        d = np.sum(n * (c[:, None] - D), axis=0)          # distance to each edge line
        # (1 - 1e-9) h: a circle shrunk to d - h below must pass despite the rounding
        bad = np.flatnonzero((d > R * cos_min * (1.0 + 1e-9)) & (d < R + (1.0 - 1e-9) * h))
        if bad.size == 0:
            return c, R
        j = int(bad[np.argmin(d[bad])])
        if user_radius:
            raise ValueError(
                f"radius: the circle meets domain edge {j} at "
                f"{np.degrees(np.arccos(min(d[j] / R, 1.0))):.0f} degrees or passes within "
                f"h of it; use radius <= {d[j] - h:.6g} or >= {d[j] / cos_min:.6g}, or a "
                "center on the wall")
        if not grown and reach + h <= d[j] - h:
            R = d[j] - h
        elif free_center and not moved[j] and not grown:
            c, R, moved[j] = c - d[j] * n[:, j], None, True
        else:
            R, grown = d[j] / cos_min * (1.0 + 1e-6), True
    raise ValueError("center: could not fit a group circle to the domain; give center and "
                     "radius")


def _in_region(tri, T: NDArray, c: NDArray, radius: float, n: int) -> NDArray[np.bool_]:
    """Triangles whose centroid lies in the fine region ``T`` (radius test first)."""
    cen = np.mean(tri.points[:, tri.t], axis=1)
    r = np.hypot(*(cen - c[:, None]))
    fine = r < radius * np.cos(np.pi / n) * (1.0 - 1e-9)
    unsure = ~fine & (r <= radius * (1.0 + 1e-9))
    fine[unsure] = inside(T, cen[:, unsure], -1e-9 * radius)
    return fine


def _positive(v: object, name: str) -> float:
    try:
        x = float(v)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a number, got {v!r}") from None
    if not (np.isfinite(x) and x > 0.0):
        raise ValueError(f"{name}: must be > 0, got {v!r}")
    return x


def _center(center: object, D: NDArray[np.float64], outlines: list) -> NDArray[np.float64]:
    if center is None:
        return np.mean([centroid(P) for P in outlines], axis=0)
    try:
        c = np.array(center, dtype=np.float64).reshape(2)
    except (TypeError, ValueError):
        raise ValueError(f"center: expected (x, y), got {center!r}") from None
    scale = float(np.max(np.ptp(D, axis=1)))
    if not np.all(np.isfinite(c)) or edge_distance(D, c[:, None])[0][0] < -1e-9 * scale:
        raise ValueError(f"center: must lie inside the domain or on its outline, got "
                         f"({c[0]:g}, {c[1]:g})")
    return c


def _fine_layout(T: NDArray[np.float64], outlines: list, h: float) -> Layout:
    """The fine region as its own layout: outline ``T`` split at ``h``, particle holes."""
    pts, edge = split_walls(T, h)
    return Layout(domain=T, edge_names=("",) * T.shape[1], particles=outlines, wall=pts,
                  wall_edge=edge, free=np.zeros((2, 0)))


def _fine_nodes(D, T, arc, fine: Layout, tri) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Split the fine mesh's nodes into fixed interior nodes and fixed wall nodes.

    Returns ``(fixed, wall_pts, wall_edge, segments)``: transition and fine
    interior nodes, fine nodes on the domain outline (corners excluded) with
    their edge index, and the transition segments coded for
    :attr:`Layout.fixed_segments`.
    """
    nb, nd = fine.n_wall, D.shape[1]
    bn = tri.points[:, :nb]
    scale = float(np.max(np.ptp(T, axis=1)))
    d, k = edge_distance(D, bn)
    on_wall = np.abs(d) <= 1e-9 * scale
    corner = np.full(nb, -1)
    for j in range(nd):
        corner[np.hypot(*(bn - D[:, j:j + 1])) <= 1e-9 * scale] = j
    is_wall = on_wall & (corner < 0)
    is_arc = ~on_wall
    steiner = tri.points[:, fine.n_frozen:]
    fixed = np.hstack([bn[:, is_arc], steiner])
    code = np.empty(nb, dtype=np.int64)
    code[is_arc] = np.arange(int(is_arc.sum()))
    code[is_wall] = -1 - (nd + np.arange(int(is_wall.sum())))
    code[corner >= 0] = -1 - corner[corner >= 0]
    arc_marker = 2 + np.flatnonzero(arc)
    sel = np.isin(tri.markers, arc_marker)
    segs = code[tri.segments[:, sel]].T
    return fixed, bn[:, is_wall], k[is_wall], segs
