"""The Taylor-Hood blocks of a moved mesh, from reference-element data.

On a mesh whose vertices move (ALE) the connectivity, the DOF numbering and
the sparsity patterns stay; only the affine maps of the triangles change.
:class:`ReferenceBlocks` keeps the reference-element integrals of the P2/P1
basis functions and the scatter maps into the fixed patterns, and builds
``M``, ``K`` (both viscous forms) and ``B`` for new vertex positions with a few
vectorised products: on a triangle with map ``x = A xhat + b``,

- ``M_e = |det A| Mhat`` (``Mhat_ij = int phi_i phi_j``),
- ``int d_c phi_i d_d phi_j = |det A| sum_kl Ainv[k, c] Ainv[l, d] S^kl_ij``
  (``S^kl_ij = int dhat_k phi_i dhat_l phi_j``), from which both viscous
  forms follow (``2 eps(u):eps(v)`` of ``u = phi_j e_d``, ``v = phi_i e_c`` is
  ``delta_cd grad phi_i . grad phi_j + d_d phi_i d_c phi_j``),
- ``-int psi_m d_d phi_j = -|det A| sum_k Ainv[k, d] E^k_mj``.

The integrals use the quadrature of the space (exact for these degrees), so
the blocks equal scikit-fem's ``asm`` of :mod:`~skfem_granular.fluid.forms` on
the moved mesh to round-off (tested).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from skfem import ElementTriP1, ElementTriP2


def affine_maps(p: np.ndarray, t: np.ndarray):
    """``A`` ``(nel, 2, 2)``, ``Ainv`` and ``det A`` ``(nel,)`` of every triangle of ``(p, t)``."""
    p0 = p[:, t[0]]
    A = np.stack([p[:, t[1]] - p0, p[:, t[2]] - p0], axis=-1).transpose(1, 0, 2)  # (nel, 2, 2)
    det = A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] * A[:, 1, 0]
    Ainv = np.empty_like(A)
    Ainv[:, 0, 0] = A[:, 1, 1] / det
    Ainv[:, 1, 1] = A[:, 0, 0] / det
    Ainv[:, 0, 1] = -A[:, 0, 1] / det
    Ainv[:, 1, 0] = -A[:, 1, 0] / det
    return A, Ainv, det


class _Pattern:
    """Fixed CSR pattern of element matrices scattered by ``(rows, cols)`` ``(nel, a, b)``."""

    def __init__(self, rows: np.ndarray, cols: np.ndarray, shape: tuple[int, int]):
        keys = rows.ravel().astype(np.int64) * shape[1] + cols.ravel()
        unique, self.slot = np.unique(keys, return_inverse=True)
        self.indices = (unique % shape[1]).astype(np.int32)
        counts = np.bincount(unique // shape[1], minlength=shape[0])
        self.indptr = np.concatenate(([0], np.cumsum(counts))).astype(np.int32)
        self.shape = shape

    def matrix(self, local: np.ndarray) -> sp.csr_matrix:
        data = np.bincount(self.slot, weights=local.ravel(), minlength=self.indices.size)
        return sp.csr_matrix((data, self.indices, self.indptr), shape=self.shape)

    def transpose_map(self):
        """``(indices, indptr, order)`` of the transposed pattern: ``A.T.data = A.data[order]``."""
        if not hasattr(self, "_transpose"):
            n = self.indices.size
            T = sp.csr_matrix((np.arange(1, n + 1, dtype=float), self.indices, self.indptr),
                              shape=self.shape).T.tocsr()
            T.sort_indices()
            self._transpose = (T.indices.copy(), T.indptr.copy(), T.data.astype(np.int64) - 1)
        return self._transpose


class ReferenceBlocks:
    """Builds the geometric blocks of a :class:`~skfem_granular.fluid.space.TaylorHood`
    for moved vertex positions.

    Parameters
    ----------
    space : TaylorHood
        The discretisation on the reference (unmoved) mesh: its connectivity,
        DOF numbering and quadrature.
    """

    def __init__(self, space):
        mesh = space.mesh
        self.t = mesh.t
        # scikit-fem does not orient triangles: a moved triangle is inverted when its
        # orientation differs from the reference one
        self.orientation = np.sign(affine_maps(mesh.p, mesh.t)[2])
        X, W = space.sb.X, space.sb.W
        p2, p1 = ElementTriP2(), ElementTriP1()
        phi = np.array([p2.lbasis(X, i)[0] for i in range(6)])  # (6, nq)
        dphi = np.array([p2.lbasis(X, i)[1] for i in range(6)])  # (6, 2, nq)
        psi = np.array([p1.lbasis(X, i)[0] for i in range(3)])  # (3, nq)
        self.phi, self.dphi, self.weights = phi, dphi, W
        self.Mhat = np.einsum("iq,jq,q->ij", phi, phi, W)
        self.S = np.einsum("ikq,jlq,q->klij", dphi, dphi, W)  # (2, 2, 6, 6)
        self.E = np.einsum("mq,jkq,q->kmj", psi, dphi, W)  # (2, 3, 6)
        sdofs = space.sb.element_dofs.T  # (nel, 6)
        vdofs = (2 * sdofs[:, :, None] + np.arange(2)).reshape(-1, 12)  # (nel, 12): 2 i + c
        pdofs = space.pb.element_dofs.T  # (nel, 3)
        nel = sdofs.shape[0]
        nu, np_ = space.nu, space.np_
        self.uu = _Pattern(np.broadcast_to(vdofs[:, :, None], (nel, 12, 12)),
                           np.broadcast_to(vdofs[:, None, :], (nel, 12, 12)), (nu, nu))
        self.pu = _Pattern(np.broadcast_to(pdofs[:, :, None], (nel, 3, 12)),
                           np.broadcast_to(vdofs[:, None, :], (nel, 3, 12)), (np_, nu))

    def blocks(self, p: np.ndarray, names=("M", "K_symmetric", "K_laplace", "B"),
               maps=None) -> dict:
        """The blocks ``names`` (of ``M``, ``K_symmetric``, ``K_laplace``, ``B``) for vertex
        positions ``p`` ``(2, nv)``; ``maps``: ``(Ainv, |det A|)`` if already known.

        Raises
        ------
        ValueError
            When a triangle is inverted or degenerate at ``p`` (never assemble on a
            negative Jacobian).
        """
        Ainv, det = self.maps(p) if maps is None else maps
        nel = det.size
        out = {}
        if "M" in names:
            Ml = np.zeros((nel, 6, 2, 6, 2))
            Ml[:, :, 0, :, 0] = Ml[:, :, 1, :, 1] = det[:, None, None] * self.Mhat
            out["M"] = self.uu.matrix(Ml)
        if "K_symmetric" in names or "K_laplace" in names:
            # G[e, c, d, i, j] = int d_c phi_i d_d phi_j over element e, as one matrix product:
            # coefficients det Ainv[k, c] Ainv[l, d] (nel, (c, d, k, l)) times S ((k, l), (i, j))
            At = Ainv.transpose(0, 2, 1)
            C = (det[:, None, None, None, None] * At[:, :, None, :, None]
                 * At[:, None, :, None, :]).reshape(nel * 4, 4)
            G = (C @ self.S.reshape(4, 36)).reshape(nel, 2, 2, 6, 6)
            Kl = np.zeros((nel, 6, 2, 6, 2))  # vector blocks ordered (e, i, c, j, d)
            Kl[:, :, 0, :, 0] = Kl[:, :, 1, :, 1] = G[:, 0, 0] + G[:, 1, 1]
            if "K_laplace" in names:
                out["K_laplace"] = self.uu.matrix(Kl)
            if "K_symmetric" in names:  # + int d_d phi_i d_c phi_j at (e, i, c, j, d)
                out["K_symmetric"] = self.uu.matrix(Kl + G.transpose(0, 3, 2, 4, 1))
        if "B" in names:
            D = Ainv.transpose(0, 2, 1).reshape(nel * 2, 2) @ self.E.reshape(2, 18)  # (e d, m j)
            Bl = -(det[:, None, None, None] * D.reshape(nel, 2, 3, 6).transpose(0, 2, 3, 1))
            out["B"] = self.pu.matrix(Bl)
        return out

    def maps(self, p: np.ndarray):
        """``Ainv`` ``(nel, 2, 2)`` and ``|det A|`` ``(nel,)`` of the triangles at ``p``.

        Raises
        ------
        ValueError
            When a triangle is inverted (orientation changed) or degenerate.
        """
        _, Ainv, det = affine_maps(p, self.t)
        signed = det * self.orientation
        if not np.all(signed > 0):
            k = int(np.argmin(signed))
            raise ValueError(f"mesh motion: triangle {k} is inverted or degenerate "
                             f"(signed area {signed[k] / 2:.3g}); remesh before moving this far")
        return Ainv, signed

    def gradients(self, Ainv: np.ndarray) -> np.ndarray:
        """Physical gradients ``(6, 2, nel, nq)`` of the P2 basis for inverse maps ``Ainv``."""
        return np.einsum("ekc,ikq->iceq", Ainv, self.dphi)
