"""Point location and evaluation of P2/P1 fields at arbitrary points.

scikit-fem's ``basis.probes`` raises for points that fall just outside a
polygonal hole and is slow for many points. :class:`PointLocator` finds the
containing triangle with a k-d tree on element centroids and a vectorised
barycentric test; points slightly outside the mesh (within ``tol`` times the
local element size) are snapped to the nearest element, points farther out
raise a clear error. Points that none of the nearest elements (by centroid)
contains, as happens in a large element next to many small ones, are tested
against every element before they count as outside. The evaluation matrix
is built from the element's own reference basis functions (``elem.lbasis``),
as ``probes`` does.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .._validate import points_array, positive

#: Points closer to the mesh than this times its diameter are always snapped.
ABS_TOL = 1e-9


class PointLocator:
    """Find the triangle of ``mesh`` that contains each point.

    Parameters
    ----------
    mesh : skfem.MeshTri
        The mesh.
    """

    def __init__(self, mesh):
        self.mesh = mesh
        P = mesh.p[:, mesh.t]  # (2, 3, nel)
        self._p0 = P[:, 0]
        e1 = P[:, 1] - P[:, 0]
        e2 = P[:, 2] - P[:, 0]
        det = e1[0] * e2[1] - e1[1] * e2[0]
        # inverse of [e1 e2] per element
        self._inv = np.array([[e2[1], -e2[0]], [-e1[1], e1[0]]]) / det
        self._e = np.stack([e1, e2])  # (2 edges, 2 coordinates, nel)
        from scipy.spatial import cKDTree  # here: scipy.spatial takes ~0.1 s to import

        self._tree = cKDTree(P.mean(axis=1).T)
        #: Points closer than this to the mesh are always snapped (round-off
        #: level for coordinates of the mesh's size, however fine the elements).
        self.abs_tol = ABS_TOL * float(np.hypot(*np.ptp(mesh.p, axis=1)))

    def locate(self, points, tol: float = 1e-6, name: str = "points"):
        """Element index and reference coordinates ``(2, n)`` of each point.

        Parameters
        ----------
        points : (2, n) array_like
            Points to locate.
        tol : float
            Points outside every element by at most ``tol`` times the local
            element size, or by at most :attr:`abs_tol` (``1e-9`` times the
            mesh's diameter), are snapped to the nearest element.
        name : str
            Name used in error messages.

        Returns
        -------
        cells : (n,) ndarray
        X : (2, n) ndarray
            Reference coordinates (clamped to the element for snapped points).
        """
        x = points_array(name, points)
        tol = positive("tol", tol, allow_zero=True)
        n = x.shape[1]
        nel = self._p0.shape[1]
        cells = np.full(n, -1)
        nearest = np.full(n, -1)
        X = np.zeros((2, n))
        best = np.full(n, -np.inf)
        for k in (min(8, nel), min(48, nel)):
            todo = np.flatnonzero(cells < 0)
            if todo.size == 0:
                break
            _, cand = self._tree.query(x[:, todo].T, k=k)
            cand = cand.reshape(todo.size, k)
            d = x[:, todo, None] - self._p0[:, cand]  # (2, m, k)
            ref = np.einsum("ijmk,jmk->imk", self._inv[:, :, cand], d)
            # smallest barycentric coordinate: >= 0 inside the element
            lam = np.minimum(np.minimum(ref[0], ref[1]), 1.0 - ref[0] - ref[1])
            j = np.argmax(lam, axis=1)
            rows = np.arange(todo.size)
            lam_j = lam[rows, j]
            better = lam_j > best[todo]
            upd = todo[better]
            best[upd] = lam_j[better]
            X[:, upd] = ref[:, rows[better], j[better]]
            nearest[upd] = cand[rows[better], j[better]]
            inside = lam_j >= -1e-12
            cells[todo[inside]] = cand[rows[inside], j[inside]]
        # far from all of the nearest elements by centroid: in a large element
        # next to many small ones, or outside; test every element (in chunks,
        # so that the first point outside stops the search)
        far = np.flatnonzero((cells < 0) & ~self._near(x, nearest, X, best, tol))
        for idx, c_all, ref_all, lam_all in self._search_all(x, far):
            better = lam_all > best[idx]
            upd = idx[better]
            best[upd], nearest[upd], X[:, upd] = lam_all[better], c_all[better], ref_all[:, better]
            out = idx[~self._near(x[:, idx], nearest[idx], X[:, idx], best[idx], tol)]
            if out.size:
                i = out[0]
                raise ValueError(f"{name}[:, {i}] = ({x[0, i]:.6g}, {x[1, i]:.6g}) lies outside "
                                 f"the mesh (farther than tol = {tol:g} element sizes and "
                                 f"{self.abs_tol:.3g})")
            found = idx[best[idx] >= -1e-12]
            cells[found] = nearest[found]
        missing = np.flatnonzero(cells < 0)
        if missing.size:  # close to an element: snap onto it
            cells[missing] = nearest[missing]
            X[:, missing] = _clamp(X[:, missing])
        return cells, X

    def _near(self, x, cells, X, lam, tol):
        """Whether points with best element ``cells`` (reference ``X``) may be snapped."""
        near = -lam <= tol
        check = np.flatnonzero(~near & (cells >= 0))
        if check.size:
            c = cells[check]
            r = _clamp(X[:, check])
            snapped = self._p0[:, c] + np.einsum("kim,km->im", self._e[:, :, c], r)
            near[check] = np.hypot(*(snapped - x[:, check])) <= self.abs_tol
        return near

    def _search_all(self, x: np.ndarray, which: np.ndarray, chunk_entries: int = 2_000_000):
        """Test points ``x[:, which]`` against every element, in chunks.

        Yields ``(idx, cells, X, lam)`` per chunk: the element of largest
        smallest barycentric coordinate ``lam`` and the reference coordinates.
        """
        nel = self._p0.shape[1]
        m = max(1, chunk_entries // max(nel, 1))
        for s0 in range(0, which.size, m):
            idx = which[s0:s0 + m]
            d = x[:, idx, None] - self._p0[:, None, :]  # (2, m, nel)
            ref = np.einsum("ijk,jmk->imk", self._inv, d)
            lam = np.minimum(np.minimum(ref[0], ref[1]), 1.0 - ref[0] - ref[1])
            j = np.argmax(lam, axis=1)
            rows = np.arange(idx.size)
            yield idx, j, ref[:, rows, j], lam[rows, j]


def _clamp(X: np.ndarray) -> np.ndarray:
    """Reference coordinates ``(2, n)`` moved into the reference triangle."""
    r = np.clip(X, 0.0, 1.0)
    s = r.sum(axis=0)
    over = s > 1.0
    r[:, over] /= s[over]
    return r


def evaluation_matrix(basis, cells: np.ndarray, X: np.ndarray) -> sp.csr_matrix:
    """Sparse ``(n, basis.N)`` matrix that evaluates a scalar field at located points."""
    elem = basis.elem
    nb = basis.element_dofs.shape[0]
    vals = np.array([elem.lbasis(X, i)[0] for i in range(nb)])  # (nb, n)
    n = cells.size
    rows = np.tile(np.arange(n), nb)
    cols = basis.element_dofs[:, cells].ravel()
    return sp.coo_matrix((vals.ravel(), (rows, cols)), shape=(n, basis.N)).tocsr()
