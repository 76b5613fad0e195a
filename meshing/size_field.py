"""The size field of field meshes: Eq. 4 growth from the nearest particle outline,
narrowed in gaps, capped at a fraction of a narrow domain's width."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .geometry import centroids, edge_distance
from .inputs import size_cap

NEAREST = 6
"""Particles (by centroid) searched for the nearest outline of a point."""


class SizeField:
    """Target edge length ``h(x)``: Eq. 4 growth from the nearest outline, narrowed in gaps.

    Parameters
    ----------
    D
        Domain outline ``(2, n)``.
    outlines
        Particle outlines (subdivided).
    sigma
        Growth factor (``None``: Eq. 4's ``1 + Delta_l / r0`` per particle).
    extra
        Optional size from outside (:mod:`meshing.size_input`): the size is then
        ``min(own, max(extra(x), h_floor))``, ``h_floor`` the smallest outline edge.

    Calling the field at points ``x`` ``(2, M)`` gives ``min(grade(x), gap(x))``:
    ``grade = min(h_max, min_k dl_k + s_k d_k(x))`` (``d_k`` the distance to outline
    ``k``, ``s_k = sigma - 1``, ``h_max`` half the domain's smallest width,
    :func:`meshing.inputs.size_cap`) and, where the two nearest boundaries
    (outlines or the wall) are closer together than two outline edges, half their
    distance.
    """

    def __init__(self, D: NDArray[np.float64], outlines: list[NDArray[np.float64]],
                 sigma: float | None, extra=None) -> None:
        from scipy.spatial import cKDTree  # here: scipy.spatial takes ~0.1 s to import

        self.D = D
        self.h_max = size_cap(D)
        self.extra = extra
        n = len(outlines)
        counts = np.array([P.shape[1] for P in outlines])
        X = np.hstack(outlines)
        first = np.cumsum(counts) - counts
        owner = np.repeat(np.arange(n), counts)
        nxt = np.arange(X.shape[1]) + 1
        nxt[first + counts - 1] = first
        E = X[:, nxt] - X
        self.centers = centroids(outlines)
        self.r0 = np.maximum.reduceat(np.hypot(*(X - self.centers.T[:, owner])), first)
        self.dl = np.add.reduceat(np.hypot(*E), first) / counts
        self.slope = self.dl / self.r0 if sigma is None else np.full(n, float(sigma) - 1.0)
        # outline edges, for the graded size
        self._edge_A, self._edge_E, self._edge_owner = X.T, E.T, owner
        self._edge_tree = cKDTree(X.T + 0.5 * E.T)
        prev = np.empty_like(nxt)
        prev[nxt] = np.arange(nxt.size)
        self._edge_prev, self._edge_next = prev, nxt
        # the polygons without their subdivision nodes (same shapes, fewer edges), for
        # the distances to whole particles: (n, m, 2), padded with empty edges
        Ep = E[:, prev]
        cross = Ep[0] * E[1] - Ep[1] * E[0]
        corner = np.abs(cross) > 1e-9 * np.hypot(*Ep) * np.hypot(*E)
        cid = np.flatnonzero(corner)
        n_c = np.bincount(owner[cid], minlength=n)
        rank = np.arange(cid.size) - np.repeat(np.cumsum(n_c) - n_c, n_c)
        m = int(n_c.max())
        A = np.repeat((X[:, cid[np.cumsum(n_c) - 1]].T)[:, None, :], m, axis=1)
        A[owner[cid], rank] = X[:, cid].T
        Ec = np.zeros((n, m, 2))
        nxt_c = np.roll(A, -1, axis=1)
        nxt_c[np.arange(n), n_c - 1] = A[:, 0]
        valid = np.arange(m)[None, :] < n_c[:, None]
        Ec[valid] = (nxt_c - A)[valid]
        self._A, self._E = A, Ec
        self._L2 = np.maximum(np.sum(Ec * Ec, axis=2), 1e-300)
        self._tree = cKDTree(self.centers)
        self.k = min(NEAREST, n)
        self.h_floor = float(self.dl.min())

    def _limited(self, x: NDArray[np.float64], h: NDArray[np.float64]) -> NDArray[np.float64]:
        """``h`` limited by the outside size, if any (never below :attr:`h_floor`)."""
        if self.extra is None:
            return h
        return np.minimum(h, np.maximum(self.extra(x), self.h_floor))

    def nearest(self, x: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
        """Distances ``(M, k)`` to the outlines of the ``k`` particles with the
        nearest centroids, and those particles' indices ``(M, k)``."""
        M = x.shape[1]
        _, idx = self._tree.query(x.T, k=self.k)
        idx = np.asarray(idx).reshape(M, self.k)
        d = np.empty((M, self.k))
        Ax, Ay, Ex, Ey = self._A[..., 0], self._A[..., 1], self._E[..., 0], self._E[..., 1]
        inv = 1.0 / self._L2
        for a in range(0, M, 8192):
            b = min(M, a + 8192)
            ii = idx[a:b]
            ex, ey = Ex[ii], Ey[ii]
            rx, ry = x[0, a:b, None, None] - Ax[ii], x[1, a:b, None, None] - Ay[ii]
            t = np.clip((rx * ex + ry * ey) * inv[ii], 0.0, 1.0)
            rx -= t * ex
            ry -= t * ey
            d[a:b] = np.sqrt(np.min(rx * rx + ry * ry, axis=2))
        return d, idx

    def closest_point(self, x: NDArray[np.float64], k: NDArray[np.int64]) -> NDArray:
        """The point of outline ``k[j]`` closest to ``x[:, j]``, ``(2, M)``."""
        R = x.T[:, None, :] - self._A[k]
        t = np.clip(np.sum(R * self._E[k], axis=2) / self._L2[k], 0.0, 1.0)
        Y = self._A[k] + t[..., None] * self._E[k]
        j = np.argmin(np.sum((x.T[:, None, :] - Y) ** 2, axis=2), axis=1)
        return Y[np.arange(x.shape[1]), j].T

    def grade(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """The graded size alone (no gap narrowing), ``(M,)``: the rule over the
        outline edge with the nearest midpoint and its two neighbours."""
        M = x.shape[1]
        if M == 0:
            return np.zeros(0)
        _, j = self._edge_tree.query(x.T)
        j = np.column_stack([j, self._edge_prev[j], self._edge_next[j]])  # (M, 3)
        A, E = self._edge_A[j], self._edge_E[j]                       # (M, 3, 2)
        Rx, Ry = x[0][:, None] - A[..., 0], x[1][:, None] - A[..., 1]
        L2 = np.maximum(E[..., 0] ** 2 + E[..., 1] ** 2, 1e-300)
        t = np.clip((Rx * E[..., 0] + Ry * E[..., 1]) / L2, 0.0, 1.0)
        d = np.hypot(Rx - t * E[..., 0], Ry - t * E[..., 1])
        own = self._edge_owner[j[:, 0]]
        h = np.minimum(self.dl[own] + self.slope[own] * np.min(d, axis=1), self.h_max)
        return self._limited(x, h)

    def __call__(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        if x.shape[1] == 0:
            return np.zeros(0)
        d, idx = self.nearest(x)
        h = self._limited(x, np.minimum(np.min(self.dl[idx] + self.slope[idx] * d, axis=1),
                                        self.h_max))
        dw = np.maximum(edge_distance(self.D, x)[0], 0.0)
        two = np.sort(np.column_stack([d, dw]), axis=1)[:, :2].sum(axis=1)
        narrow = two < 2.0 * self.dl[idx[:, 0]]
        return np.where(narrow, np.minimum(h, 0.5 * two), h)
