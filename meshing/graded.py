"""Graded meshes from concentric circles around particles (paper Section 5).

Around a particle with circumradius ``r0`` (about its centroid) and outline
edge length ``Delta_l``, circles with radii ``r_{i+1} = r_i + Delta_l r_i / r0``
(Eq. 4, i.e. ``r_i = r0 sigma**i`` with ``sigma = 1 + Delta_l / r0``) carry one
node per outline node, projected radially outwards; every odd circle is
rotated by half the angular spacing (staggered). The nodes are truncated at
the domain, fitted to its outline, cleaned of degenerate triangles, relaxed
and joined by a constrained Delaunay triangulation.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import skfem
from numpy.typing import NDArray

from .cleanup import Sizing, truncate, wall_nodes
from .geometry import MAX_ELEMENTS, centroid, outline_lengths
from .inputs import check_rounds, check_sigma, prepare, size_cap
from .pslg import Layout
from .registry import builds
from .repair import build
from .skfem_mesh import to_body_fitted
from .value import BodyFittedMesh, Recipe

DL_MAX_RATIO = 2.0 * float(np.sin(np.pi / 10.0))
"""Largest outline edge length over circumradius for graded circles (a 10-gon)."""


@dataclass(frozen=True)
class Rings:
    """Concentric circles around one particle or group.

    ``center`` ``(2,)``; ``r0`` the particle's circumradius; ``dl`` its
    outline edge length; ``sigma`` the growth factor; ``radii`` ``(n,)``
    with ``radii[0] = r0``; ``counts`` ``(n,)`` nodes per circle
    (``counts[0]`` = outline nodes).
    """

    center: NDArray[np.float64]
    r0: float
    dl: float
    sigma: float
    radii: NDArray[np.float64]
    counts: NDArray[np.int64]
    h_max: float = np.inf


def default_sigma(dl: float, r0: float) -> float:
    """Growth factor of Eq. 4: ``sigma = 1 + Delta_l / r0``."""
    return 1.0 + dl / r0


def ring_radii(r0: float, sigma: float, r_max: float, dl: float | None = None,
               h_max: float | None = None) -> NDArray[np.float64]:
    """Circle radii from ``r0`` up to the first one beyond ``r_max``.

    The spacing starts at ``dl`` and grows by ``sigma`` per circle:
    ``r_{i+1} = r_i + dl sigma**i``. With ``dl = (sigma - 1) r0`` (the
    default, and Eq. 4's ``sigma = 1 + dl / r0``) this is
    ``r_{i+1} = r_i + dl r_i / r0``, i.e. ``r_i = r0 sigma**i``. A spacing
    that would exceed ``h_max`` is ``h_max`` (equally spaced circles from there).
    """
    q = sigma - 1.0
    if dl is None:
        dl = q * r0
    n = int(np.ceil(np.log(1.0 + max(r_max - r0, 0.0) * q / dl) / np.log(sigma) - 1e-9))
    i = np.arange(n + 1, dtype=np.float64)  # as sigma ** int would cast it: same numbers
    r = r0 * sigma ** i if dl == q * r0 else r0 + dl * (sigma ** i - 1.0) / q
    if h_max is None or not np.any(np.diff(r) > h_max):
        return r
    k = int(np.argmax(np.diff(r) > h_max))
    m = max(1, int(np.ceil((r_max - r[k]) / h_max - 1e-9)))
    return np.concatenate([r[:k + 1], r[k] + h_max * np.arange(1, m + 1)])


def rings(outline: NDArray[np.float64], sigma: float | None, r_max: float,
          center: NDArray[np.float64] | None = None, h_max: float | None = None) -> Rings:
    """The :class:`Rings` of an outline (already subdivided).

    Circle ``i`` has ``N (r_i / r0) (dl / d_i)`` nodes (``d_i = dl sigma**i``
    its spacing, at most ``h_max``, ``N`` the outline's node count), so that the
    node spacing along it matches the spacing to the next circle: ``N`` on every
    circle for Eq. 4's default sigma, fewer for a larger one, more beyond the cap.
    """
    c = centroid(outline) if center is None else center
    r0 = float(np.max(np.hypot(*(outline - c[:, None]))))
    dl = float(np.mean(outline_lengths(outline)))
    s = default_sigma(dl, r0) if sigma is None else sigma
    radii = ring_radii(r0, s, r_max, None if sigma is None else dl, h_max)
    d = dl * s ** np.arange(radii.size)
    if h_max is not None:
        d = np.minimum(d, h_max)
    N = outline.shape[1]
    counts = np.maximum(3, np.rint(N * radii / r0 * dl / d)).astype(np.int64)
    counts[0] = N
    return Rings(center=c, r0=r0, dl=dl, sigma=s, radii=radii, counts=counts,
                 h_max=np.inf if h_max is None else float(h_max))


def ring_nodes(outline: NDArray[np.float64], ring: Rings) -> NDArray[np.float64]:
    """Nodes on circles ``1, 2, ...``, ``(2, M)``, ring by ring.

    A circle with as many nodes as the outline carries the outline nodes'
    polar angles (even circles) or the angular midpoints between
    consecutive outline nodes (odd circles: the stagger by half a spacing).
    A circle with fewer nodes spaces them evenly, odd circles again shifted
    by half a spacing.
    """
    d = outline - ring.center[:, None]
    th = np.arctan2(d[1], d[0])
    dth = np.mod(np.roll(th, -1) - th, 2.0 * np.pi)
    mid = th + 0.5 * dth
    parts = []
    for i, (r, n) in enumerate(zip(ring.radii[1:], ring.counts[1:], strict=True), start=1):
        if n == outline.shape[1]:
            phi = mid if i % 2 else th
        else:
            phi = th[0] + 2.0 * np.pi * (np.arange(n) + 0.5 * (i % 2)) / n
        parts.append(ring.center[:, None] + r * np.vstack([np.cos(phi), np.sin(phi)]))
    return np.hstack(parts) if parts else np.zeros((2, 0))


def sizing_of(all_rings: Sequence[Rings]) -> Sizing:
    """Size field of a set of circle families: the circle spacing, linear in
    the radius, ``dl + (sigma - 1)(r - r0)`` (``dl r / r0`` for Eq. 4), capped at the
    smallest of their ``h_max``."""
    C = np.array([r.center for r in all_rings])
    dl = np.array([r.dl for r in all_rings])
    s = np.array([r.sigma - 1.0 for r in all_rings])
    r0 = np.array([r.r0 for r in all_rings])
    return Sizing(C, dl, s, r0, h_max=min(r.h_max for r in all_rings))


def check_ring_nodes(all_rings: Sequence[Rings], sigma, delta_l) -> None:
    """Refuse circles with more than :data:`~meshing.geometry.MAX_ELEMENTS` nodes in all
    (an upper bound of the mesh's nodes, counted before any is placed)."""
    n = sum(int(r.counts.sum()) for r in all_rings)
    if n > MAX_ELEMENTS:
        raise ValueError(f"delta_l = {delta_l!r}, sigma = {sigma!r}: the graded circles would "
                         f"hold {n:.3g} nodes, more than {MAX_ELEMENTS:.0e}; use a larger "
                         "delta_l or sigma")


def graded_mesh(domain: object = (0.0, 0.0, 3e-3, 11e-3), particles: object = (),
                sigma: float | None = None, delta_l: float | None = None, *,
                relax_rounds: int = 4) -> skfem.MeshTri:
    """Graded triangle mesh around particles (concentric circles, Eq. 4).

    Parameters
    ----------
    domain
        ``(x0, y0, x1, y1)`` rectangle or a convex counter-clockwise
        ``(2, N)`` outline.
    particles
        List of convex counter-clockwise ``(2, N)`` outlines (or objects with
        ``.vertices``), disjoint and strictly inside the domain; at least one.
    sigma
        Growth factor of the element size from one circle to the next,
        ``1 < sigma <= 1.6``; default ``1 + Delta_l / r0`` (Eq. 4) per
        particle, ``r0`` its circumradius about its centroid and ``Delta_l``
        its mean outline edge length. The circle spacing starts at
        ``Delta_l`` and grows by ``sigma``: ``r_{i+1} = r_i + Delta_l
        sigma**i``, which for the default is Eq. 4, ``r_{i+1} = r_i + Delta_l
        r_i / r0``, with one node per outline node on every circle. Another
        sigma changes the node count per circle so that node spacing and
        circle spacing stay equal (isotropic triangles).
    delta_l
        Outline resolution: ``None`` keeps each outline's own edges; a value
        ``0 < delta_l <= r0`` (smallest particle's circumradius) splits every
        edge into equal parts no longer than ``delta_l``; the new nodes lie on
        the straight edges. Graded circles need outline edges no longer than
        ``0.618 r0`` (a regular 10-gon's). Particle outline nodes are never
        moved.
    relax_rounds
        Rounds of spring relaxation (each followed by re-triangulation),
        ``0 <= relax_rounds <= 20``; 0 skips relaxation.

    Returns
    -------
    skfem.MeshTri
        With ``boundaries`` ``"wall"`` (and ``"bottom"``, ``"right"``,
        ``"top"``, ``"left"`` for a rectangle), ``"particle0"``, ...
        ``meshing.build("graded", domain, particles, ...)`` returns the same
        mesh as a :class:`meshing.BodyFittedMesh`, with its recipe and the
        particles' outline vertex indices.

    The element size stops growing at half the domain's smallest width
    (:data:`meshing.inputs.WIDTH_FRACTION`): past it the circles are equally spaced.

    Quality: minimum angle >= 20 degrees and ``R / (2 r) <= 3`` (see
    :func:`meshing.mesh_stats`) whenever particles keep at least one outline
    edge length from the walls and from each other, in channels of any aspect
    ratio (tested up to 1:50). Closer, the unsplit
    outline edge and the wall leave no room for good triangles; the mesh is
    still valid (no inverted element, complete boundaries).

    Several particles get one set of circles each; a node is kept only where
    its own particle's size field is the smallest, so circles of different
    particles do not interpenetrate. For dense groups use
    :func:`meshing.group_mesh`.
    """
    return build_graded(domain, particles, sigma=sigma, delta_l=delta_l,
                        relax_rounds=relax_rounds).mesh


@builds("graded")
def build_graded(domain: object, particles: object, *, sigma: float | None = None,
                 delta_l: float | None = None, relax_rounds: int = 4) -> BodyFittedMesh:
    """:func:`graded_mesh` as a :class:`~meshing.value.BodyFittedMesh`.

    What :func:`meshing.build` calls for ``kind="graded"``; the arguments and
    the mesh are those of :func:`graded_mesh`.
    """
    sigma = check_sigma(sigma)
    check_rounds(relax_rounds)
    D, names, outlines = prepare(domain, particles, delta_l)
    if not outlines:
        raise ValueError("particles: graded_mesh needs at least one particle "
                         "(use uniform_mesh for an empty domain)")
    all_rings = []
    for k, P in enumerate(outlines):
        r0 = float(np.max(np.hypot(*(P - centroid(P)[:, None]))))
        dl = float(np.mean(outline_lengths(P)))
        if dl > DL_MAX_RATIO * r0 * (1.0 + 1e-9):
            raise ValueError(f"particles[{k}]: outline edges (mean length {dl:.6g}) are "
                             f"longer than {DL_MAX_RATIO:.3f} r0 = {DL_MAX_RATIO * r0:.6g} "
                             "(a regular 10-gon's); graded circles need a finer outline: "
                             f"pass delta_l <= {DL_MAX_RATIO * r0:.6g}")
        c = centroid(P)
        r_max = float(np.max(np.hypot(*(D - c[:, None]))))
        all_rings.append(rings(P, sigma, r_max, h_max=size_cap(D)))
    check_ring_nodes(all_rings, sigma, delta_l)
    sizing = sizing_of(all_rings)
    cand = []
    for p, (P, ring) in enumerate(zip(outlines, all_rings, strict=True)):
        x = ring_nodes(P, ring)
        if len(outlines) > 1:
            x = x[:, np.argmin(sizing.per_source(x), axis=0) == p]
        cand.append(x)
    free, proj, proj_edge = truncate(D, outlines, np.hstack(cand), sizing)
    wall, wall_edge = wall_nodes(D, proj, proj_edge, sizing)
    layout = Layout(domain=D, edge_names=names, particles=outlines, wall=wall,
                    wall_edge=wall_edge, free=free)
    layout, tri = build(layout, sizing, outlines, relax_rounds)
    recipe = Recipe("graded", domain, tuple(outlines),
                    dict(sigma=sigma, delta_l=delta_l, relax_rounds=relax_rounds))
    return to_body_fitted(tri, layout, recipe)
