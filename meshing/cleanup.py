"""Fitting candidate nodes to a domain: size field, truncation, projection,
wall nodes, and merging of degenerate triangles."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from .geometry import edge_distance, outline_lengths, project_to_edge
from .pslg import Layout, Triangulation, triangulate
from .quality import MERGE_ASPECT, angles, aspect_ratio, edge_lengths, signed_areas

PROJECT_FRACTION = 0.5
"""Nodes closer to the domain outline than this times the local size are
projected onto it; nodes closer to a particle are dropped."""

SHORT_FRACTION = 0.6
"""An edge shorter than this times the local size makes a bad triangle a needle
(merged by removing a node); a flat cap's apex is that close to its base."""

WALL_MERGE_FRACTION = 0.5
"""Wall nodes closer than this times the local size are merged."""


#: What the cleanup, relaxation and repair read of a mesh's size rule: the target edge
#: length ``(M,)`` at points ``(2, M)`` (:class:`Sizing`, a field mesh's SizeField).
SizeRule = Callable[[NDArray[np.float64]], NDArray[np.float64]]


class Sizing:
    """Target edge length ``h(x) = min(h_max, min_k max(dl_k, dl_k + s_k (|x - c_k| - r0_k)))``.

    Each source ``k`` is a particle (or a group's circle) with centre ``c_k``,
    radius ``r0_k``, surface edge length ``dl_k`` and growth slope
    ``s_k = sigma_k - 1``: on circles whose spacing grows by ``sigma`` per
    circle, ``d_{i+1} - d_i = (sigma - 1)(r_{i+1} - r_i)``, so the spacing is
    linear in the radius. With Eq. 4's default ``sigma = 1 + dl / r0`` this
    is ``h = dl r / r0``, the ring spacing ``r_{i+1} - r_i = dl r_i / r0``.
    ``h_max`` caps the growth (a fraction of a narrow domain's width, see
    :func:`meshing.inputs.size_cap`; infinite by default).
    """

    def __init__(self, centers: NDArray[np.float64], dl: NDArray[np.float64],
                 slope: NDArray[np.float64], r0: NDArray[np.float64],
                 h_max: float = np.inf) -> None:
        self.h_max = float(h_max)
        self.centers = np.atleast_2d(np.asarray(centers, dtype=np.float64))
        self.dl = np.atleast_1d(np.asarray(dl, dtype=np.float64))
        self.slope = np.atleast_1d(np.asarray(slope, dtype=np.float64))
        self.offset = self.dl - self.slope * np.atleast_1d(np.asarray(r0, dtype=np.float64))
        self._tree = None
        if self.dl.size > 8:
            from scipy.spatial import cKDTree  # here: scipy.spatial takes ~0.1 s to import

            self._tree = cKDTree(self.centers)

    def per_source(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Sizes of every source at ``x``, shape ``(k, M)``."""
        r = np.hypot(x[0][None, :] - self.centers[:, 0:1], x[1][None, :] - self.centers[:, 1:2])
        h = np.maximum(self.dl[:, None], self.offset[:, None] + self.slope[:, None] * r)
        return np.minimum(h, self.h_max)

    def __call__(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        if x.shape[1] == 0:
            return np.zeros(0)
        if self._tree is None:
            return self.per_source(x).min(axis=0)
        # the nearest few centres decide the minimum for similar sources
        _, idx = self._tree.query(x.T, k=min(8, self.dl.size))
        r = np.hypot(x[0][:, None] - self.centers[idx, 0], x[1][:, None] - self.centers[idx, 1])
        h = np.maximum(self.dl[idx], self.offset[idx] + self.slope[idx] * r).min(axis=1)
        return np.minimum(h, self.h_max)


def near_particles(particles: Sequence[NDArray[np.float64]], x: NDArray[np.float64],
                   gap: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Points inside a particle or closer than ``gap`` (per point) to one."""
    bad = np.zeros(x.shape[1], dtype=bool)
    if not particles or x.shape[1] == 0:
        return bad
    few = len(particles) <= 8
    tree = None
    if not few:
        from scipy.spatial import cKDTree  # here: scipy.spatial takes ~0.1 s to import

        tree = cKDTree(x.T)
    gmax = float(gap.max())
    for P in particles:
        c = P.mean(axis=1)
        R = float(np.max(np.hypot(*(P - c[:, None]))))
        if few:
            idx = np.arange(x.shape[1])
        else:
            assert tree is not None  # built above for many particles
            idx = np.asarray(tree.query_ball_point(c, R + gmax), dtype=np.int64)
        if idx.size:
            idx = idx[np.hypot(*(x[:, idx] - c[:, None])) <= R + gap[idx]]
        if idx.size:
            d, _ = edge_distance(P, x[:, idx])
            bad[idx[d > -gap[idx]]] = True
    return bad


def truncate(D: NDArray[np.float64], particles: Sequence[NDArray[np.float64]],
             x: NDArray[np.float64], sizing: SizeRule,
             fraction: float = PROJECT_FRACTION) -> tuple[NDArray, NDArray, NDArray]:
    """Drop candidate nodes outside the domain, project near-wall ones onto it.

    Returns ``(free, wall_points, wall_edge)``: interior nodes kept, and the
    projections ``(2, k)`` with the index of the domain edge they lie on.
    Nodes inside a particle or closer than ``fraction * h`` to one are dropped.
    """
    d, k = edge_distance(D, x)
    keep = d > 0.0
    x, d, k = x[:, keep], d[keep], k[keep]
    h = sizing(x)
    near = d < fraction * h
    s = project_to_edge(D, k[near], x[:, near])
    E = np.roll(D, -1, axis=1) - D
    E = E / np.hypot(*E)
    wall = D[:, k[near]] + s * E[:, k[near]]
    free = x[:, ~near]
    free = free[:, ~near_particles(particles, free, fraction * h[~near])]
    return free, wall, k[near]


def wall_nodes(D: NDArray[np.float64], proj: NDArray[np.float64], proj_edge: NDArray,
               sizing: SizeRule, fixed: NDArray[np.float64] | None = None,
               fixed_edge: NDArray | None = None,
               fraction: float = WALL_MERGE_FRACTION) -> tuple[NDArray, NDArray]:
    """Nodes along the domain outline: corners, fixed nodes, projected nodes, gap fillers.

    Projected nodes closer than ``fraction * h`` to a kept one (or a corner
    or fixed node) are merged; gaps longer than ``1.5 h`` (``h`` at the gap's
    midpoint) are split evenly. Returns ``(points (2, n), edge index (n,))``
    ordered corners, ``fixed`` (unchanged), then the others.
    """
    nd = D.shape[1]
    L = outline_lengths(D)
    E = (np.roll(D, -1, axis=1) - D) / L
    if fixed is None:
        fixed, fixed_edge = np.zeros((2, 0)), np.zeros(0, dtype=np.int64)
    pts, edges = [D, fixed], [np.arange(nd), np.asarray(fixed_edge, dtype=np.int64)]
    for j in range(nd):
        mine = proj_edge == j
        s = np.sort(np.hypot(*(proj[:, mine] - D[:, j:j + 1])))
        hs = sizing(D[:, j:j + 1] + s * E[:, j:j + 1])
        fix = np.hypot(*(fixed[:, fixed_edge == j] - D[:, j:j + 1]))
        anchors = np.sort(np.concatenate([[0.0, L[j]], fix]))
        h_anchor = sizing(D[:, j:j + 1] + anchors * E[:, j:j + 1])
        kept: list[float] = []
        for sk, hk in zip(s, hs, strict=True):
            far = np.abs(anchors - sk) >= fraction * np.maximum(hk, h_anchor)
            if np.all(far) and (not kept or sk - kept[-1] >= fraction * hk):
                kept.append(float(sk))
        allpos = np.sort(np.concatenate([anchors, kept]))
        new = []
        for a, b in zip(allpos[:-1], allpos[1:], strict=True):
            hm = float(sizing(D[:, j:j + 1] + 0.5 * (a + b) * E[:, j:j + 1])[0])
            n = int(np.rint((b - a) / hm))
            if n >= 2:
                new.extend(a + (b - a) * np.arange(1, n) / n)
        s_all = np.array(sorted(kept + new))
        pts.append(D[:, j:j + 1] + s_all * E[:, j:j + 1])
        edges.append(np.full(s_all.size, j))
    return np.hstack(pts), np.concatenate(edges)


def movable(layout: Layout) -> NDArray[np.bool_]:
    """Which nodes cleanup may delete: free nodes and non-corner wall nodes."""
    m = np.zeros(layout.points().shape[1], dtype=bool)
    m[layout.n_wall_frozen:layout.n_wall] = True
    m[layout.n_frozen:] = True
    return m


def remove_nodes(layout: Layout, drop: NDArray[np.int64]) -> Layout:
    """Layout without the given node indices (free or non-corner wall nodes)."""
    nw, nf = layout.n_wall, layout.n_frozen
    keep_wall = np.ones(nw, dtype=bool)
    keep_wall[drop[drop < nw]] = False
    keep_free = np.ones(layout.free.shape[1], dtype=bool)
    keep_free[drop[drop >= nf] - nf] = False
    return replace(layout, wall=layout.wall[:, keep_wall],
                   wall_edge=layout.wall_edge[keep_wall], free=layout.free[:, keep_free])


def degenerate_nodes(tri: Triangulation, can_go: NDArray[np.bool_], sizing: SizeRule,
                     max_aspect: float = MERGE_ASPECT,
                     short: float = SHORT_FRACTION) -> NDArray[np.int64]:
    """Nodes whose removal merges each degenerate triangle with its neighbours.

    For every triangle with ``R / (2 r) > max_aspect``: if its shortest edge
    is shorter than ``short * h`` (a needle), an endpoint of that edge that
    may be removed; else if its widest-angle vertex lies closer than
    ``short * h`` to the opposite edge (a flat cap), that vertex. Free nodes
    are preferred over wall nodes. Triangles that are bad because of a
    *large* gap are left to relaxation and repair: removing nodes there
    would make them worse.
    """
    q = aspect_ratio(tri.points, tri.t)
    bad = np.flatnonzero(q > max_aspect)
    if bad.size == 0:
        return np.zeros(0, dtype=np.int64)
    p = tri.points
    t = tri.t[:, bad]
    L = edge_lengths(p, t)
    ang = angles(p, t)
    h = sizing(p[:, t].mean(axis=1))
    area = np.abs(signed_areas(p, t))
    out = set()
    for j in range(bad.size):
        k = int(np.argmin(L[:, j]))
        cands = []
        if L[k, j] < short * h[j]:
            ends = [int(t[(k + 1) % 3, j]), int(t[(k + 2) % 3, j])]
            cands = [v for v in ends if can_go[v]]
        if not cands:
            w = int(np.argmax(ang[:, j]))
            v = int(t[w, j])
            if can_go[v] and 2.0 * area[j] / L[w, j] < short * h[j]:
                cands = [v]
        if cands:
            # prefer the free node (the larger index: free nodes come last)
            out.add(max(cands))
    return np.array(sorted(out), dtype=np.int64)


def merge_degenerate(layout: Layout, sizing: SizeRule, max_aspect: float = MERGE_ASPECT,
                     rounds: int = 4, tri: Triangulation | None = None
                     ) -> tuple[Layout, Triangulation]:
    """Remove nodes of degenerate triangles and re-triangulate until none is left
    that removing a movable node can fix (at most ``rounds`` passes); ``tri``:
    the layout's triangulation when the caller already has it."""
    if tri is None:
        tri = triangulate(layout)
    for _ in range(rounds):
        drop = degenerate_nodes(tri, movable(layout), sizing, max_aspect)
        if drop.size == 0:
            break
        layout = remove_nodes(layout, drop)
        tri = triangulate(layout)
    return layout, tri
