"""Fast convection terms from precomputed element data.

scikit-fem's generic ``asm`` re-evaluates basis functions on every call. The
convection term is the only state-dependent block of the Navier-Stokes
system, so :class:`ConvectionKernel` keeps the P2 basis values, gradients and
quadrature weights per element and evaluates ``N(a) b`` vectors, the Newton
Jacobian's action and the Jacobian matrix itself with ``numpy.einsum`` into a
fixed sparsity pattern. The results equal the forms
:data:`~skfem_granular.fluid.forms.convection` and
:data:`~skfem_granular.fluid.forms.convection_newton` (tested).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from skfem import Basis


class ConvectionKernel:
    """Convection ``((a . grad) b, v)`` on a P2 vector space.

    Parameters
    ----------
    scalar_basis : skfem.Basis
        Scalar P2 basis on the mesh, with the quadrature of the vector basis.
        Vector DOF ``2 k + c`` is component ``c`` of scalar DOF ``k``.
    """

    def __init__(self, scalar_basis: Basis):
        sb = scalar_basis
        self.edofs = sb.element_dofs  # (6, nel)
        nloc = self.edofs.shape[0]
        self.phi = np.array([np.asarray(sb.basis[i][0]) for i in range(nloc)])  # (6, nel, nq)
        self.dphi = np.array([sb.basis[i][0].grad for i in range(nloc)])  # (6, 2, nel, nq)
        self.dx = sb.dx  # (nel, nq)
        self.nu = 2 * sb.N
        # Jacobian pattern: local entry (e, i, c, j, d) -> row 2 edof_i + c, col 2 edof_j + d
        vdofs = 2 * self.edofs.T[:, :, None] + np.arange(2)[None, None, :]  # (nel, 6, 2)
        rows = np.broadcast_to(vdofs[:, :, :, None, None], (vdofs.shape[0], nloc, 2, nloc, 2))
        cols = np.broadcast_to(vdofs[:, None, None, :, :], rows.shape)
        keys = rows.ravel().astype(np.int64) * self.nu + cols.ravel()
        unique, self._slot = np.unique(keys, return_inverse=True)
        self._indices = (unique % self.nu).astype(np.int32)
        counts = np.bincount(unique // self.nu, minlength=self.nu)
        self._indptr = np.concatenate(([0], np.cumsum(counts))).astype(np.int32)
        self._vdofs = vdofs

    def _fields(self, a: np.ndarray):
        """Values ``(2, nel, nq)`` and gradients ``(2, 2, nel, nq)`` of P2 field ``a``."""
        A = a.reshape(-1, 2)[self.edofs]  # (6, nel, 2)
        val = np.einsum("iec,ieq->ceq", A, self.phi)
        grd = np.einsum("iec,ideq->cdeq", A, self.dphi)
        return val, grd

    def _scatter(self, local: np.ndarray) -> np.ndarray:
        """Sum element vectors ``(2, 6, nel)`` into a global vector."""
        idx = 2 * self.edofs[None, :, :] + np.arange(2)[:, None, None]
        return np.bincount(idx.ravel(), weights=local.ravel(), minlength=self.nu)

    def apply(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Vector of ``((a . grad) b, v_i)`` for all test functions ``v_i``."""
        va, ga = self._fields(a)
        gb = ga if b is a else self._fields(b)[1]
        adv = np.einsum("cdeq,deq->ceq", gb, va) * self.dx
        return self._scatter(np.einsum("ceq,ieq->cie", adv, self.phi))

    def residual(self, u: np.ndarray) -> np.ndarray:
        """``N(u) u``."""
        return self.apply(u, u)

    def jacobian_action(self, u: np.ndarray, du: np.ndarray) -> np.ndarray:
        """Newton linearisation at ``u`` applied to ``du``: ``N(u) du + N(du) u``."""
        vu, gu = self._fields(u)
        vd, gd = self._fields(du)
        adv = (np.einsum("cdeq,deq->ceq", gd, vu) + np.einsum("cdeq,deq->ceq", gu, vd)) * self.dx
        return self._scatter(np.einsum("ceq,ieq->cie", adv, self.phi))

    def jacobian(self, u: np.ndarray, newton: bool = True) -> sp.csr_matrix:
        """Matrix of the convection term linearised at ``u``.

        Parameters
        ----------
        u : ndarray
            Velocity DOFs (the wind).
        newton : bool
            ``True``: full Newton Jacobian ``N(u) . + N(.) u``; ``False``:
            Picard (Oseen) matrix ``N(u)``.
        """
        vu, gu = self._fields(u)
        wphi = self.phi * self.dx  # (6, nel, nq)
        # term 1: delta_cd phi_i (u . grad phi_j)
        ugphi = np.einsum("deq,jdeq->jeq", vu, self.dphi)
        T1 = np.einsum("ieq,jeq->eij", wphi, ugphi)
        nel, nloc = T1.shape[0], T1.shape[1]
        local = np.zeros((nel, nloc, 2, nloc, 2))
        local[:, :, 0, :, 0] = T1
        local[:, :, 1, :, 1] = T1
        if newton:
            # term 2: phi_i phi_j d_d u_c
            local += np.einsum("ieq,jeq,cdeq->eicjd", wphi, self.phi, gu)
        data = np.bincount(self._slot, weights=local.ravel(), minlength=self._indices.size)
        return sp.csr_matrix((data, self._indices, self._indptr), shape=(self.nu, self.nu))
