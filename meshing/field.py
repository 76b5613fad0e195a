"""Graded meshes from a size field around many particles (kind ``"field"``).

The element size grows linearly with the distance ``d`` from the *nearest*
particle outline, as the circle spacing of the paper's Eq. 4 does with the
radius: ``h = Delta_l + (sigma - 1) d`` (Eq. 4 itself is ``sigma = 1 +
Delta_l / r0``, ``h = Delta_l (1 + d / r0)``; the default is the paper's
``sigma = 1.2`` for particle groups, :data:`FIELD_SIGMA`). Because the distance
is to the nearest outline, a cluster of grains keeps a fine region that hugs
the cluster, and grains spread over a floor keep fine elements only around
themselves. The rule depends on the outlines alone, so every remesh grades
around where the grains are now.

Construction:

1. the domain outline is split at the size field along it, finer where a
   particle is close to the wall (half the gap);
2. outline edges facing a gap narrower than two outline edges get nodes at a
   third of the gap's width (:func:`meshing.gaps.split_gap_edges`);
3. a first layer of nodes over every outline: the apex of the equilateral
   triangle on each outline edge (the paper's first staggered circle) and one
   node off each corner; where the gap to another outline or the wall is
   narrower than that (:data:`GAP_FRACTION`), the nodes are pulled into the
   gap: half way across a gap between two particles, 0.6 of the way to a
   wall, from every outline node and edge midpoint facing the gap, so that
   every narrow gap holds a row of interior nodes;
4. ``triangle`` fills the rest (minimum angle, area bounds from the size field
   at the vertices, no Steiner point on any outline or wall segment);
5. cleanup and repair as for the other graded meshes (degenerate triangles
   merged, bad ones repaired) and a last check that no mesh edge joins two
   different outlines (or an outline and the wall): such an edge is split.

Outline nodes are never moved and outline edges are split only in step 2
(the polygon is the same; ``particle_nodes`` are its vertices, the added nodes
lie on its boundary ``"particle{k}"``).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import skfem
import triangle
from numpy.typing import NDArray

from .cleanup import merge_degenerate
from .gaps import GAP_SPACING, split_gap_edges
from .geometry import centroids
from .inputs import check_rounds, check_sigma, prepare
from .layer import GAP_FRACTION, WALL_FRACTION, layer_nodes
from .pslg import Layout, Triangulation, fixed_point, triangulate
from .quality import angles_and_aspect, signed_areas
from .registry import builds
from .relax import relax
from .repair import REPAIR_ROUNDS, SAFE_MAX_ASPECT, SAFE_MIN_ANGLE, circumcenters, repair_nodes
from .size_field import SizeField
from .size_input import as_size
from .skfem_mesh import to_body_fitted
from .uniform import AREA_FACTOR
from .value import BodyFittedMesh, Recipe

MIN_ANGLE = 28.0
"""Minimum angle (degrees) requested from ``triangle`` for the fill."""

FIELD_SIGMA = 1.2
"""Default growth factor per element layer: the paper's value for particle
groups. Eq. 4's own rate, ``1 + Delta_l / r0`` (1.5 for the collapse's cores at
``delta_l`` = 0.2 mm), leaves less margin: forces on a block moving in a closed
box within 0.44 % of the fine mesh against 0.125 % with 1.2, pore flux of a
touching honeycomb 0.61 % against 0.53 % (docs/meshing.md)."""

OVERSIZE = 1e-3
"""Fraction of the fill's triangles that may stay above their area bound (the
last refinements of ``triangle`` each fix a handful of triangles)."""

MAX_FIELD_ELEMENTS = 2_000_000
"""Default of ``max_elements``."""

SPLIT_ROUNDS = 3
"""Rounds of splitting edges that join two outlines."""

def wall_points(D: NDArray[np.float64], field: SizeField) -> tuple[NDArray, NDArray]:
    """Corners, then nodes splitting each domain edge at the size field along it.

    The node count on an edge is the integral of ``1 / h`` along it (rounded),
    the nodes equidistant in that integral. Returns ``(points, edge index)``.
    """
    nd = D.shape[1]
    step = 0.125 * float(np.min(field.dl))
    pts, edges = [D], [np.arange(nd)]
    for j in range(nd):
        a, b = D[:, j:j + 1], D[:, (j + 1) % nd:(j + 1) % nd + 1]
        L = float(np.hypot(*(b - a)[:, 0]))
        s = np.linspace(0.0, L, int(np.ceil(L / step)) + 2)
        inv = 1.0 / field(a + (b - a) * (s / L))
        F = np.concatenate([[0.0], np.cumsum(0.5 * (inv[1:] + inv[:-1]) * np.diff(s))])
        n = max(1, int(np.rint(F[-1])))
        sj = np.interp(np.arange(1, n) * (F[-1] / n), F, s)
        pts.append(a + (b - a) * (sj / L))
        edges.append(np.full(sj.size, j))
    return np.hstack(pts), np.concatenate(edges)


def _pslg(layout: Layout) -> dict:
    """``triangle`` input of a layout (walls, outlines, fixed and free nodes)."""
    from .pslg import boundary_segments

    segs, marks, _ = boundary_segments(layout)
    return {"vertices": layout.points().T, "segments": segs, "segment_markers": marks[:, None],
            "holes": centroids(layout.particles)}


def fill(layout: Layout, field: SizeField, max_elements: int, rule: str
         ) -> tuple[NDArray, Triangulation]:
    """Steiner points of a quality, size-bounded ``triangle`` mesh of the layout,
    and that mesh (the constrained Delaunay triangulation of the layout with them).

    A triangle's size is the mean of the graded size at its vertices; each
    refinement keeps the vertices before it (``triangle``'s ``r`` switch), so
    only new vertices are evaluated. Refinement stops when at most
    :data:`OVERSIZE` of the triangles exceed their area bound. Raises ValueError
    (naming ``rule``) when the size field would need more than ``max_elements``
    triangles.
    """
    data = _pslg(layout)
    n0 = data["vertices"].shape[0]
    switches = f"pq{fixed_point(MIN_ANGLE)}YQS{int(max_elements)}"
    out = triangle.triangulate(data, switches)
    known, hv = np.zeros((0, 2)), np.zeros(0)
    for _ in range(12):
        p, t = out["vertices"].T, out["triangles"].T
        k = known.shape[0]
        if k > p.shape[1] or not np.array_equal(out["vertices"][:k], known):
            k, hv = 0, np.zeros(0)
        hv = np.concatenate([hv, field.grade(p[:, k:])])
        known = out["vertices"]
        h = hv[t].mean(axis=0)
        bound = AREA_FACTOR * np.sqrt(3.0) / 4.0 * h * h
        area = np.abs(signed_areas(p, t))
        estimate = float(np.sum(np.maximum(area / bound, 1.0)))
        if estimate > max_elements:
            raise ValueError(f"{rule}: the size field would give about {estimate:.3g} "
                             f"triangles, more than max_elements = {max_elements}; use a "
                             "larger delta_l or sigma, or raise max_elements")
        over = area > bound * (1.0 + 1e-9)
        if np.sum(over) <= OVERSIZE * over.size:
            break
        data = {"vertices": out["vertices"], "triangles": out["triangles"],
                "segments": out["segments"], "segment_markers": out["segment_markers"],
                "holes": data["holes"], "triangle_max_area": np.where(over, bound, -1.0)[:, None]}
        out = triangle.triangulate(data, "r" + switches + "a")
    tri = Triangulation(points=np.ascontiguousarray(out["vertices"].T),
                        t=out["triangles"].T.astype(np.int64),
                        segments=out["segments"].T.astype(np.int64),
                        markers=out["segment_markers"].ravel().astype(np.int64))
    return np.ascontiguousarray(out["vertices"][n0:].T), tri


def finish(layout: Layout, field: SizeField, relax_rounds: int,
           tri: Triangulation | None = None) -> tuple[Layout, Triangulation]:
    """Merge degenerate triangles, optionally relax, repair bad ones (no relaxation
    between repairs: the first layer is already in place); ``tri``: the layout's
    triangulation if known."""
    layout, tri = merge_degenerate(layout, field, tri=tri)
    if relax_rounds:
        layout = relax(layout, field, layout.particles, rounds=relax_rounds)
        layout, tri = merge_degenerate(layout, field)
    for _ in range(REPAIR_ROUNDS):
        free, wall, wall_edge = repair_nodes(layout, tri, layout.particles)
        if free.shape[1] + wall.shape[1] == 0:
            break
        before = (layout.free.shape[1], layout.wall.shape[1])
        layout = replace(layout, free=np.hstack([layout.free, free]),
                         wall=np.hstack([layout.wall, wall]),
                         wall_edge=np.concatenate([layout.wall_edge, wall_edge]))
        layout, tri = merge_degenerate(layout, field)
        if (layout.free.shape[1], layout.wall.shape[1]) == before:
            break       # the merge took out as many nodes as the repair put in: no progress
    return layout, tri


def _star_quality(p: NDArray[np.float64], t: NDArray[np.int64]) -> float:
    """Worst of (min angle / 20 deg, 3 / aspect) over triangles ``t``; <= 0 if one inverts."""
    if np.any(signed_areas(p, t) <= 0.0):
        return -1.0
    ang, q = angles_and_aspect(p, t)
    return float(min(np.min(ang) / SAFE_MIN_ANGLE, np.min(SAFE_MAX_ASPECT / q)))


def smooth_bad(tri, first_movable: int, rounds: int = 6) -> bool:
    """Move interior nodes of triangles outside the quality bounds, in place.

    For each interior node (index >= ``first_movable``) of a bad triangle, the
    positions between it and the centroid of its neighbours (and towards the
    centroid of its star's circumcentres, or the apex that would make the bad
    triangle equilateral) are tried; the best that improves the worst triangle
    of its star is kept. Connectivity is unchanged. Returns whether bad
    triangles are left.
    """
    p, t = tri.points, tri.t
    for _ in range(rounds):
        ang, q = angles_and_aspect(p, t)
        bad = (ang.min(axis=0) < SAFE_MIN_ANGLE) | (q > SAFE_MAX_ASPECT)
        if not np.any(bad):
            return False
        nodes = np.unique(t[:, bad])
        nodes = nodes[nodes >= first_movable]
        if nodes.size == 0:
            return True
        moved = False
        for v in nodes:
            star = t[:, np.any(t == v, axis=0)]
            ring = np.unique(star)
            ring = ring[ring != v]
            x0 = p[:, v].copy()
            best, q_best = x0, _star_quality(p, star)
            targets = [p[:, ring].mean(axis=1), circumcenters(p, star).mean(axis=1)]
            for tb in t[:, bad & np.any(t == v, axis=0)].T:
                k = int(np.flatnonzero(tb == v)[0])
                a, b = p[:, tb[(k + 1) % 3]], p[:, tb[(k + 2) % 3]]
                e = b - a
                # apex of the equilateral triangle on the opposite edge (ccw: left of a->b)
                targets.append(0.5 * (a + b) + 0.5 * np.sqrt(3.0) * np.array([-e[1], e[0]]))
            for y in targets:
                for w in (1.0, 0.6, 0.3):
                    p[:, v] = x0 + w * (y - x0)
                    quality = _star_quality(p, star)
                    if quality > q_best + 1e-9:
                        best, q_best = p[:, v].copy(), quality
            p[:, v] = best
            moved |= bool(np.any(best != x0))
        if not moved:
            return True
    return True


def boundary_component(layout: Layout, n_points: int) -> NDArray[np.int64]:
    """Per node: 0 on the domain outline, ``k + 1`` on particle ``k``'s outline, -1 inside."""
    comp = np.full(n_points, -1, dtype=np.int64)
    comp[:layout.n_wall] = 0
    off = layout.n_wall
    for k, P in enumerate(layout.particles):
        comp[off:off + P.shape[1]] = k + 1
        off += P.shape[1]
    return comp


def joining_edges(layout: Layout, t: NDArray[np.int64], n_points: int
                  ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Mesh edges ``(2, E)`` whose two nodes lie on different outlines (or an
    outline and the wall), and the components of their ends ``(2, E)``."""
    comp = boundary_component(layout, n_points)
    e = np.sort(np.hstack([t[[0, 1]], t[[1, 2]], t[[2, 0]]]), axis=0)
    c = comp[e]
    e = e[:, (c[0] >= 0) & (c[1] >= 0) & (c[0] != c[1])]
    e = np.unique(e[0] * n_points + e[1])
    e = np.vstack([e // n_points, e % n_points])
    c = comp[e]
    bad = (c[0] >= 0) & (c[1] >= 0) & (c[0] != c[1])
    return e[:, bad], c[:, bad]


def field_mesh(domain: object = (0.0, 0.0, 3e-3, 11e-3), particles: object = (),
               sigma: float | None = None, delta_l: float | None = None, *,
               max_elements: int = MAX_FIELD_ELEMENTS, relax_rounds: int = 0,
               size: object = None, gap_spacing: float | None = None) -> skfem.MeshTri:
    """Graded mesh around many particles from a size field (module notes).

    Parameters
    ----------
    domain, particles, delta_l
        As in :func:`meshing.graded_mesh` (at least one particle).
    sigma
        Growth factor of the element size per element layer, ``1 < sigma <=
        1.6``: ``h = Delta_l + (sigma - 1) d`` at distance ``d`` from the
        nearest outline (Eq. 4's linear growth of the spacing with the
        distance); default :data:`FIELD_SIGMA` = 1.2, the paper's value for
        particle groups. ``sigma = 1 + Delta_l / r0`` is Eq. 4 itself,
        ``h = Delta_l (1 + d / r0)``.
    max_elements
        Most triangles the rule may ask for (estimated from the size field
        while filling); more raises ValueError. An integer ``>= 100``.
    relax_rounds
        Spring relaxation rounds of the fill nodes, ``0 <= relax_rounds <= 20``.
    size
        An outside target edge length (e.g. from a flow indicator): a callable
        ``size(x) -> (M,)`` for points ``(2, M)``, or ``(points (2, N), values (N,))``
        interpolated linearly after limiting their growth to ``sigma - 1`` per unit
        distance (:mod:`meshing.size_input`). The mesh follows ``min(rule, max(size,
        smallest outline edge))``; ``max_elements`` bounds it.
    gap_spacing
        Outline node spacing along a narrow gap as a fraction of its width (default
        :data:`meshing.gaps.GAP_SPACING` = 1/3, about three elements across);
        ``0.1 <= gap_spacing``, ``math.inf`` leaves the gaps unlined (the outline
        edges alone). docs/meshing.md measures what a coarser lining costs in accuracy.

    Returns
    -------
    skfem.MeshTri
        Named boundaries as in :func:`meshing.graded_mesh`.
        ``meshing.build("field", ...)`` returns the same mesh as a
        :class:`meshing.BodyFittedMesh`.

    Quality: minimum angle >= 20 degrees and ``R / (2 r) <= 3`` (measured on
    touching clusters, gaps of 0.87 outline edges between cores and 0.43 to the
    floor: 23.8-28.1 degrees; two cores 0.01 edges apart: 20.4). Outline edges
    along a gap narrower than two outline edges carry nodes a third of the gap
    apart, so about three elements lie across it; no edge joins two outlines.
    """
    return build_field(domain, particles, sigma=sigma, delta_l=delta_l,
                       max_elements=max_elements, relax_rounds=relax_rounds, size=size,
                       gap_spacing=gap_spacing).mesh


def check_max_elements(max_elements: object) -> int:
    if (not isinstance(max_elements, int | np.integer) or isinstance(max_elements, bool)
            or max_elements < 100):
        raise ValueError(f"max_elements: must be an integer >= 100, got {max_elements!r}")
    return int(max_elements)


def check_gap_spacing(gap_spacing: object) -> float:
    """``gap_spacing`` as a float (default :data:`~meshing.gaps.GAP_SPACING`), or ValueError."""
    if gap_spacing is None:
        return GAP_SPACING
    if (isinstance(gap_spacing, bool) or not isinstance(gap_spacing, int | float | np.number)
            or not gap_spacing >= 0.1):
        raise ValueError(f"gap_spacing: must be a number >= 0.1 (a fraction of the gap's "
                         f"width; math.inf: gaps unlined), got {gap_spacing!r}")
    return float(gap_spacing)


def _split_joining(layout, tri, field):
    """Split the edges that join two outlines, or an outline and a wall (node inserted,
    mesh finished again), up to :data:`SPLIT_ROUNDS` times."""
    for _ in range(SPLIT_ROUNDS):
        e, c = joining_edges(layout, tri.t, tri.points.shape[1])
        if e.shape[1] == 0:
            break
        f = np.where(c[0] == 0, 1.0 - WALL_FRACTION, np.where(c[1] == 0, WALL_FRACTION,
                                                                GAP_FRACTION))
        a, b = tri.points[:, e[0]], tri.points[:, e[1]]
        layout = replace(layout, fixed=np.hstack([layout.fixed, a + f * (b - a)]),
                         free=tri.points[:, layout.n_frozen:])
        layout, tri = finish(layout, field, 0)
    return layout, tri


def _smooth_bad(layout, tri):
    """Smooth the nodes of poor triangles and let them reconnect, twice at most; a round is
    kept only if no edge joins two outlines and the worst star got no worse."""
    first = layout.n_wall + layout.n_particle_nodes
    for _ in range(2):
        if not smooth_bad(tri, first):
            break
        nf = layout.fixed.shape[1]
        trial = replace(layout, fixed=tri.points[:, first:first + nf],
                        free=tri.points[:, first + nf:])
        tri2 = triangulate(trial)
        if (joining_edges(trial, tri2.t, tri2.points.shape[1])[0].shape[1] == 0
                and _star_quality(tri2.points, tri2.t) >= _star_quality(tri.points, tri.t)):
            layout, tri = trial, tri2
        else:
            break
    return layout, tri


@builds("field")
def build_field(domain: object, particles: object, *, sigma: float | None = None,
                delta_l: float | None = None, max_elements: int = MAX_FIELD_ELEMENTS,
                relax_rounds: int = 0, size: object = None,
                gap_spacing: float | None = None) -> BodyFittedMesh:
    """:func:`field_mesh` as a :class:`~meshing.value.BodyFittedMesh`.

    What :func:`meshing.build` calls for ``kind="field"``.
    """
    sigma = check_sigma(sigma)
    check_rounds(relax_rounds)
    max_elements = check_max_elements(max_elements)
    spacing = check_gap_spacing(gap_spacing)
    D, names, outlines = prepare(domain, particles, delta_l)
    if not outlines:
        raise ValueError("particles: field_mesh needs at least one particle "
                         "(use uniform_mesh for an empty domain)")
    rule = f"delta_l = {delta_l!r}, sigma = {sigma!r}"
    n_outline = sum(P.shape[1] for P in outlines)
    if n_outline > max_elements:
        raise ValueError(f"{rule}: {n_outline} outline nodes alone exceed max_elements = "
                         f"{max_elements}; use a larger delta_l or raise max_elements")
    s = FIELD_SIGMA if sigma is None else sigma
    field = SizeField(D, outlines, s, as_size(size, slope=s - 1.0))
    wall, wall_edge = wall_points(D, field)
    if wall.shape[1] > max_elements:
        raise ValueError(f"{rule}: {wall.shape[1]} wall nodes alone exceed max_elements = "
                         f"{max_elements}; use a larger delta_l or raise max_elements")
    nd = D.shape[1]
    split, vertices = split_gap_edges(D, outlines, field, spacing)
    n_split = sum(P.shape[1] for P in split)
    if n_split > max_elements:
        raise ValueError(f"{rule}: {n_split} outline nodes with the narrow gaps lined exceed "
                         f"max_elements = {max_elements}; use a larger delta_l or raise "
                         "max_elements")
    layout = Layout(domain=D, edge_names=names, particles=split, wall=wall,
                    wall_edge=wall_edge, free=np.zeros((2, 0)),
                    fixed=layer_nodes(D, split, field), n_wall_fixed=wall.shape[1] - nd)
    free, tri = fill(layout, field, max_elements, rule)
    layout = replace(layout, free=free)
    layout, tri = finish(layout, field, relax_rounds, None if relax_rounds else tri)
    layout, tri = _split_joining(layout, tri, field)
    layout, tri = _smooth_bad(layout, tri)
    recipe = Recipe("field", domain, tuple(outlines),
                    dict(sigma=sigma, delta_l=delta_l, max_elements=max_elements,
                         relax_rounds=relax_rounds, **({} if size is None else {"size": size}),
                         **({} if gap_spacing is None else {"gap_spacing": gap_spacing})))
    return to_body_fitted(tri, layout, recipe, outline_vertices=vertices)
