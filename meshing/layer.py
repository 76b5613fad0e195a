"""The first layer of nodes of a field mesh, pulled into narrow gaps.

Over every outline edge the apex of the equilateral triangle on it (the paper's
first staggered circle), and a node off every corner on its bisector. Where the
gap to another outline or the wall is narrower than that, the nodes go
:data:`GAP_FRACTION` of the way across (between two particles, so that facing
particles meet in the middle) or :data:`WALL_FRACTION` of the way to a wall,
from every outline node and edge midpoint facing the gap: every narrow gap
holds a row of interior nodes. Nodes closer than half their spacing are merged.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .geometry import edge_distance, inside, project_to_edge

if TYPE_CHECKING:
    from .size_field import SizeField

GAP_FRACTION = 0.5
"""A first-layer node lies at most this fraction of the way across a gap to
another particle (so facing particles meet in the middle)."""

WALL_FRACTION = 0.6
"""... and at most this fraction of the way to a wall (whose side is split
finer, at half the gap)."""

CORNER_TURN = 20.0
"""Outline vertices turning by more than this (degrees) are corners: they get a
first-layer node on their bisector."""


def nearest_wall_point(D: NDArray[np.float64], x: NDArray[np.float64]) -> NDArray:
    """Closest point of the domain outline to each of ``x``, ``(2, M)``."""
    _, k = edge_distance(D, x)
    E = np.roll(D, -1, axis=1) - D
    return D[:, k] + project_to_edge(D, k, x) * E[:, k] / np.hypot(*E[:, k])


def _samples(outlines: list[NDArray[np.float64]]) -> tuple:
    """Where the first layer starts, per particle its edge midpoints then its nodes:
    points ``S``, directions ``N`` (outward normals, bisectors at nodes), target heights
    ``T``, owners and kinds (0 edge midpoint, 1 node, 2 corner)."""
    counts = np.array([P.shape[1] for P in outlines])
    X = np.hstack(outlines)
    start = np.cumsum(counts) - counts
    owner = np.repeat(np.arange(counts.size), counts)
    nxt = np.arange(X.shape[1]) + 1
    nxt[start + counts - 1] = start
    prev = np.empty_like(nxt)
    prev[nxt] = np.arange(nxt.size)
    E = X[:, nxt] - X
    L = np.hypot(*E)
    n = np.vstack([E[1], -E[0]]) / L
    n_prev = n[:, prev]
    bis = n + n_prev
    bis /= np.hypot(*bis)
    corner = np.arccos(np.clip(np.sum(n * n_prev, axis=0), -1.0, 1.0)) > np.radians(CORNER_TURN)
    # per particle its edge midpoints, then its nodes
    order = np.argsort(np.concatenate([2 * owner, 2 * owner + 1]), kind="stable")
    S = np.hstack([0.5 * (X + X[:, nxt]), X])[:, order]
    N = np.hstack([n, bis])[:, order]
    T = np.concatenate([0.5 * np.sqrt(3.0) * L, 0.5 * (L + L[prev])])[order]
    own = np.concatenate([owner, owner])[order]
    kind = np.concatenate([np.zeros(L.size, dtype=np.int8),
                           np.where(corner, 2, 1).astype(np.int8)])[order]
    return S, N, T, own, kind


def layer_nodes(D: NDArray[np.float64], outlines: list[NDArray[np.float64]],
                field: SizeField) -> NDArray[np.float64]:
    """The first layer of nodes over every outline, pulled into narrow gaps (module notes)."""
    S, N, T, own, kind = _samples(outlines)
    d, idx = field.nearest(S)
    d = np.where(idx == own[:, None], np.inf, d)
    j = np.argmin(d, axis=1)
    dc = d[np.arange(S.shape[1]), j]
    other = idx[np.arange(S.shape[1]), j]
    dw = np.maximum(edge_distance(D, S)[0], 0.0)
    to_wall = dw < dc
    frac = np.where(to_wall, WALL_FRACTION, GAP_FRACTION)
    gap = np.minimum(dc, dw)
    narrow = frac * gap < T
    # target of a narrow sample: the closest point across the gap
    Y = np.empty_like(S)
    if np.any(narrow & ~to_wall):
        sel = narrow & ~to_wall
        Y[:, sel] = field.closest_point(S[:, sel], other[sel])
    if np.any(narrow & to_wall):
        sel = narrow & to_wall
        Y[:, sel] = nearest_wall_point(D, S[:, sel])
    X = S + N * T
    # edge midpoints and plain nodes in a gap: across it
    across = narrow & (kind < 2)
    X[:, across] = S[:, across] + frac[across] * (Y[:, across] - S[:, across])
    # corners: along the bisector, as far as the free length along it allows
    cor = kind == 2
    free = ray_free(D, field, S[:, cor], N[:, cor], own[cor])
    frac_ray = np.where(free[1], WALL_FRACTION, GAP_FRACTION)
    X[:, cor] = S[:, cor] + N[:, cor] * np.minimum(T[cor], frac_ray * free[0])
    keep = (kind != 1) | narrow
    spacing = np.where(narrow, np.minimum(T, gap), T)
    # a corner in a gap also gets the node across it (closes the gap's mouth)
    extra = narrow & cor
    X = np.hstack([X[:, keep], S[:, extra] + frac[extra] * (Y[:, extra] - S[:, extra])])
    spacing = np.concatenate([spacing[keep], np.minimum(T, gap)[extra]])
    X, spacing = _merge_close(X, spacing)
    ok = inside(D, X, 0.0) & (edge_distance(D, X)[0] > 0.2 * spacing)
    X, spacing = X[:, ok], spacing[ok]
    if X.shape[1]:
        dx, _ = field.nearest(X)
        X = X[:, dx.min(axis=1) > 0.2 * spacing]
    return X


def ray_free(D: NDArray[np.float64], field: SizeField, S: NDArray[np.float64],
             N: NDArray[np.float64], own: NDArray[np.int64]) -> tuple[NDArray, NDArray]:
    """Free length along the rays ``S + s N`` (``s > 0``) up to another outline
    (of the particles nearest to ``S``) or the domain outline, and whether the
    wall is what the ray meets first."""
    M = S.shape[1]
    if M == 0:
        return np.zeros(0), np.zeros(0, dtype=bool)
    # domain (convex, S inside): exit distance over every edge line
    E = np.roll(D, -1, axis=1) - D
    nrm = np.vstack([-E[1], E[0]]) / np.hypot(*E)                    # inward normals
    dist = np.sum(nrm[:, :, None] * (S[:, None, :] - D[:, :, None]), axis=0)   # (edges, M)
    towards = -np.sum(nrm[:, :, None] * N[:, None, :], axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        s_wall = np.where(towards > 1e-12, dist / towards, np.inf).min(axis=0)
    _, idx = field.nearest(S)
    best = np.full(M, np.inf)
    for c in range(idx.shape[1]):
        k = idx[:, c]
        P0, Ek = field._A[k], field._E[k]                               # (M, v, 2)
        W = P0 - S.T[:, None, :]
        den = N.T[:, None, 0] * Ek[..., 1] - N.T[:, None, 1] * Ek[..., 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (W[..., 0] * Ek[..., 1] - W[..., 1] * Ek[..., 0]) / den
            u = (W[..., 0] * N.T[:, None, 1] - W[..., 1] * N.T[:, None, 0]) / den
        hit = (np.abs(den) > 1e-300) & (s > 0.0) & (u >= 0.0) & (u <= 1.0)
        s = np.where(hit & (k[:, None] != own[:, None]), s, np.inf).min(axis=1)
        best = np.minimum(best, s)
    return np.minimum(best, s_wall), s_wall <= best


def _merge_close(X: NDArray[np.float64], spacing: NDArray[np.float64]
                 ) -> tuple[NDArray, NDArray]:
    """Replace nodes closer than half their spacing by their mean (in index order)."""
    if X.shape[1] < 2:
        return X, spacing
    from scipy.spatial import cKDTree  # here: scipy.spatial takes ~0.1 s to import

    pairs = cKDTree(X.T).query_pairs(0.5 * float(spacing.max()), output_type="ndarray")
    if pairs.size == 0:
        return X, spacing
    dist = np.hypot(*(X[:, pairs[:, 0]] - X[:, pairs[:, 1]]))
    pairs = pairs[dist < 0.5 * np.minimum(spacing[pairs[:, 0]], spacing[pairs[:, 1]])]
    pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
    keep = np.ones(X.shape[1], dtype=bool)
    X = X.copy()
    for i, k in pairs:
        if keep[i] and keep[k]:
            X[:, i] = 0.5 * (X[:, i] + X[:, k])
            keep[k] = False
    return X[:, keep], spacing[keep]
