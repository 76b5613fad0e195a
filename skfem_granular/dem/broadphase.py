"""Broad phase: candidate pairs from bounding circles (k-d tree, Verlet margin).

Pairs are returned as two index arrays ``(i, j)``; particle-particle pairs
have ``i < j < N``, particle-wall pairs have ``j = N + w`` for wall ``w``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["NeighbourList", "circle_pairs", "wall_pairs"]


def circle_pairs(X: np.ndarray, radius: np.ndarray, margin: float = 0.0):
    """Pairs of particles whose bounding circles (enlarged by ``margin``) meet.

    Parameters
    ----------
    X
        ``(2, N)`` centres.
    radius
        ``(N,)`` bounding radii.
    margin
        Added to the sum of the two radii.

    Returns
    -------
    i, j
        ``int64`` arrays with ``i < j``, sorted lexicographically.
    """
    N = X.shape[1]
    if N < 2:
        e = np.zeros(0, dtype=np.int64)
        return e, e
    from scipy.spatial import cKDTree  # here: scipy.spatial takes ~0.1 s to import

    tree = cKDTree(X.T)
    P = tree.query_pairs(r=2.0 * float(radius.max()) + margin, output_type="ndarray")
    if P.size == 0:
        e = np.zeros(0, dtype=np.int64)
        return e, e
    i, j = P[:, 0].astype(np.int64), P[:, 1].astype(np.int64)
    swap = i > j
    i[swap], j[swap] = j[swap], i[swap]
    d = X[:, i] - X[:, j]
    keep = (d * d).sum(axis=0) < (radius[i] + radius[j] + margin) ** 2
    i, j = i[keep], j[keep]
    order = np.lexsort((j, i))
    return i[order], j[order]


def wall_pairs(X: np.ndarray, radius: np.ndarray, wall_vertices: np.ndarray, margin: float = 0.0):
    """Particle-wall pairs whose distance is below the bounding radius plus ``margin``.

    Parameters
    ----------
    X
        ``(2, N)`` centres; ``radius`` ``(N,)`` bounding radii.
    wall_vertices
        ``(W, nmax, 2)`` padded counter-clockwise wall outlines.

    Returns
    -------
    i, w
        Particle and wall indices.
    """
    W = wall_vertices.shape[0]
    N = X.shape[1]
    if W == 0 or N == 0:
        e = np.zeros(0, dtype=np.int64)
        return e, e
    A = wall_vertices[None]  # (1, W, n, 2)
    B = np.roll(wall_vertices, -1, axis=1)[None]
    p = X.T[:, None, None, :]  # (N, 1, 1, 2)
    e = B - A
    ap = p - A
    ee = (e * e).sum(axis=-1)
    t = np.clip((ap * e).sum(axis=-1) / np.where(ee > 0, ee, 1.0), 0.0, 1.0)
    d = ap - t[..., None] * e
    dist2 = (d * d).sum(axis=-1).min(axis=-1)  # (N, W)
    inside = np.all(e[..., 0] * ap[..., 1] - e[..., 1] * ap[..., 0] >= 0.0, axis=-1)
    near = inside | (dist2 < (radius[:, None] + margin) ** 2)
    i, w = np.nonzero(near)
    return i.astype(np.int64), w.astype(np.int64)


class NeighbourList:
    """Verlet list: candidate pairs rebuilt only after large displacements.

    Parameters
    ----------
    margin
        Skin distance added to the bounding circles. The list is rebuilt when
        a particle has moved more than ``margin / 2`` since the last build,
        so no contact is ever missed.
    """

    def __init__(self, margin: float):
        self.margin = float(margin)
        self.reference: np.ndarray | None = None
        self.pairs: tuple[np.ndarray, np.ndarray] | None = None
        self.builds = 0

    def invalidate(self) -> None:
        """Force a rebuild at the next :meth:`update`."""
        self.reference = None

    def update(self, X: np.ndarray, radius: np.ndarray, wall_vertices: np.ndarray):
        """Candidate pairs ``(i, j)`` for centres ``X`` (walls as ``j = N + w``)."""
        if self.reference is not None and self.reference.shape == X.shape:
            d = X - self.reference
            if float((d * d).sum(axis=0).max(initial=0.0)) < (0.5 * self.margin) ** 2:
                return self.pairs
        i, j = circle_pairs(X, radius, self.margin)
        iw, w = wall_pairs(X, radius, wall_vertices, self.margin)
        N = X.shape[1]
        self.pairs = (np.concatenate([i, iw]), np.concatenate([j, N + w]))
        self.reference = X.copy()
        self.builds += 1
        return self.pairs
