"""Fast convection terms from precomputed element data.

scikit-fem's generic ``asm`` re-evaluates basis functions on every call. The
convection term is the only state-dependent block of the Navier-Stokes
system, so :class:`ConvectionKernel` keeps the triangles' affine maps and the
reference element's basis values, gradients and quadrature weights and evaluates
``N(a) b`` vectors and the Newton Jacobian's action, and the Jacobian matrix on a
fixed sparsity pattern, each in one compiled pass over the triangles
(:mod:`~skfem_granular.fluid.convection_numba`).
The results equal the forms
:data:`~skfem_granular.fluid.forms.convection` and
:data:`~skfem_granular.fluid.forms.convection_newton` (tested).
"""

from __future__ import annotations

import copy
from typing import Protocol

import numpy as np
import scipy.sparse as sp

from .geometry import scatter_pattern


class Convection(Protocol):
    """What the operators use of a convection evaluator: :class:`ConvectionKernel` or
    :class:`~skfem_granular.fluid.forms_assembly.FormsConvection`."""

    @property
    def pattern(self) -> tuple[np.ndarray, np.ndarray]: ...

    def apply(self, a: np.ndarray, b: np.ndarray) -> np.ndarray: ...

    def apply_relative(self, u: np.ndarray, w: np.ndarray, convection: bool = True
                       ) -> np.ndarray: ...

    def residual(self, u: np.ndarray) -> np.ndarray: ...

    def jacobian_action(self, u: np.ndarray, du: np.ndarray) -> np.ndarray: ...

    def relative_jacobian_action(self, u: np.ndarray, w: np.ndarray, du: np.ndarray
                                 ) -> np.ndarray: ...

    def jacobian(self, u: np.ndarray, newton: bool = True) -> sp.csr_matrix: ...

    def jacobian_data(self, u: np.ndarray, newton: bool = True,
                      out: np.ndarray | None = None) -> np.ndarray: ...


def element_pattern(edofs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The CSR pattern of every 12 x 12 element matrix of a P2 vector field on a mesh.

    Parameters
    ----------
    edofs : (6, nel) ndarray
        Scalar P2 DOFs of every triangle (vector DOF ``2 k + c`` is component ``c`` of
        scalar DOF ``k``).

    Returns
    -------
    slot : (nel * 144,) int32 ndarray
        Value slot of local entry ``(e, i, c, j, d)`` (row ``2 edof_i + c``, column
        ``2 edof_j + d``).
    indices, indptr : int32 ndarray
        The pattern (:func:`~skfem_granular.fluid.geometry.scatter_pattern`).
    """
    from .pattern_numba import vector_pattern

    # the scalar P2 pattern (36 couplings per triangle), expanded by the 2 x 2 component
    # blocks: vector row 2 k + c holds columns 2 j, 2 j + 1 for each scalar column j of row
    # k, in order (a quarter of the keys to sort)
    nloc, nel = edofs.shape
    ns = int(edofs.max()) + 1
    E = np.ascontiguousarray(edofs.T)
    sslot, sind, sptr = scatter_pattern(np.broadcast_to(E[:, :, None], (nel, nloc, nloc)),
                                        np.broadcast_to(E[:, None, :], (nel, nloc, nloc)),
                                        (ns, ns))
    return vector_pattern(E, sslot, sind, sptr)


class ConvectionActions:
    """What a convection derives from its two primitives: :meth:`apply` ``((a . grad) b,
    v_i)`` and ``_vector(a, ca, w, cw, b)`` ``(((ca a - cw w) . grad) b, v_i)``: the ALE
    convection, the residual and the Newton actions (shared by the compiled kernel and
    the scikit-fem path, :class:`~.forms_assembly.FormsConvection`)."""

    def apply(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _vector(self, a, ca, w, cw, b) -> np.ndarray:
        raise NotImplementedError

    def apply_relative(self, u: np.ndarray, w: np.ndarray, convection: bool = True
                       ) -> np.ndarray:
        """``(((u - w) . grad) u, v_i)`` (``convection``) or ``((-w . grad) u, v_i)``: the ALE
        convection of ``u`` on a mesh moving with velocity ``w``."""
        return self._vector(u, 1.0 if convection else 0.0, w, 1.0, u)

    def residual(self, u: np.ndarray) -> np.ndarray:
        """``N(u) u``."""
        return self.apply(u, u)

    def jacobian_action(self, u: np.ndarray, du: np.ndarray) -> np.ndarray:
        """Newton linearisation at ``u`` applied to ``du``: ``N(u) du + N(du) u``."""
        return self.apply(u, du) + self.apply(du, u)

    def relative_jacobian_action(self, u: np.ndarray, w: np.ndarray, du: np.ndarray
                                 ) -> np.ndarray:
        """Linearisation of the ALE convection ``((u - w) . grad) u`` (:meth:`apply_relative`)
        at ``u`` applied to ``du``: ``((u - w) . grad) du + (du . grad) u``."""
        return self._vector(u, 1.0, w, 1.0, du) + self.apply(du, u)


class ConvectionKernel(ConvectionActions):
    """Convection ``((a . grad) b, v)`` on a P2 vector space.

    Parameters
    ----------
    edofs : (6, nel) int ndarray
        Scalar P2 DOFs of every triangle; vector DOF ``2 k + c`` is component ``c``
        of scalar DOF ``k``.
    maps : (nel, 5) ndarray
        The triangles' affine maps, ``Ainv[0, 0], Ainv[1, 0], Ainv[0, 1], Ainv[1, 1],
        |det A|`` (:meth:`~skfem_granular.fluid.geometry.ReferenceBlocks.moved` with
        ``"convection"``).
    reference : tuple of ndarray
        ``(phi, dref, weights)``: the P2 basis values ``(6, nq)`` and reference
        gradients ``(6, 2, nq)`` at the quadrature points of the reference triangle,
        and the quadrature weights ``(nq,)``.
    pattern : tuple of ndarray, optional
        ``(slot, indices, indptr)`` of :func:`element_pattern` of ``edofs``, if already
        built.
    """

    def __init__(self, edofs: np.ndarray, maps: np.ndarray, reference: tuple,
                 pattern: tuple | None = None):
        self.edofs = edofs  # (6, nel)
        phi, dref, weights = (np.ascontiguousarray(a, dtype=float) for a in reference)
        if edofs.ndim != 2 or edofs.shape[0] != 6 or edofs.dtype.kind not in "iu":
            raise ValueError(f"edofs: shape {edofs.shape}, dtype {edofs.dtype}; expected "
                             "integers of shape (6, nel)")
        nel, nq = edofs.shape[1], weights.size
        for name, a, expected in (("maps", maps, (nel, 5)), ("reference[0] (phi)", phi, (6, nq)),
                                  ("reference[1] (dref)", dref, (6, 2, nq)),
                                  ("reference[2] (weights)", weights, (nq,))):
            if a.shape != expected:
                raise ValueError(f"{name}: shape {a.shape}, expected {expected} "
                                 f"({nel} triangles, {nq} quadrature points)")
        self._maps = np.ascontiguousarray(maps, dtype=float)
        self._reference = (phi, dref, weights)
        self.nu = 2 * (int(edofs.max()) + 1)
        #: value slot of local entry (e, i, c, j, d) in :attr:`pattern` (int32)
        self.slot, self._indices, self._indptr = (element_pattern(edofs) if pattern is None
                                                  else pattern)
        self._edofs_e = np.ascontiguousarray(edofs.T, dtype=np.int64)  # (nel, 6)

    def with_maps(self, maps: np.ndarray) -> ConvectionKernel:
        """The same kernel on a moved mesh, from the affine maps ``(nel, 5)`` of its
        triangles; DOFs, reference element and the sparsity pattern are this kernel's."""
        if maps.shape != self._maps.shape:
            raise ValueError(f"maps: shape {maps.shape}, expected {self._maps.shape}")
        new = copy.copy(self)
        new._maps = np.ascontiguousarray(maps, dtype=float)
        return new

    def apply(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Vector of ``((a . grad) b, v_i)`` for all test functions ``v_i``."""
        return self._vector(a, 1.0, a, 0.0, b)

    def _vector(self, a, ca, w, cw, b) -> np.ndarray:
        """``(((ca a - cw w) . grad) b, v_i)``, one compiled pass
        (:func:`~skfem_granular.fluid.convection_numba.convection_vector`)."""
        from .convection_numba import convection_vector

        out = np.zeros(self.nu)
        convection_vector(self._velocity("a", a), float(ca), self._velocity("w", w),
                          float(cw), self._velocity("b", b), self._edofs_e, self._maps,
                          *self._reference, out)
        return out

    def _velocity(self, name: str, v) -> np.ndarray:
        """``v`` as a contiguous float vector of the ``nu`` velocity DOFs (the compiled
        passes do not check their indices)."""
        v = np.ascontiguousarray(v, dtype=float)
        if v.shape != (self.nu,):
            raise ValueError(f"{name}: shape {v.shape}, expected ({self.nu},): the velocity "
                             "DOFs of this kernel's mesh")
        return v

    def jacobian(self, u: np.ndarray, newton: bool = True) -> sp.csr_matrix:
        """Matrix of the convection term linearised at ``u`` (see :meth:`jacobian_data`)."""
        data = self.jacobian_data(u, newton)
        return sp.csr_matrix((data, self._indices, self._indptr), shape=(self.nu, self.nu))

    @property
    def pattern(self) -> tuple[np.ndarray, np.ndarray]:
        """``(indices, indptr)`` of the CSR pattern shared by every :meth:`jacobian`."""
        return self._indices, self._indptr

    def jacobian_data(self, u: np.ndarray, newton: bool = True,
                      out: np.ndarray | None = None) -> np.ndarray:
        """Values of :meth:`jacobian` on its fixed pattern (:attr:`pattern`).

        Parameters
        ----------
        u : ndarray
            Velocity DOFs (the wind).
        newton : bool
            ``True``: full Newton Jacobian ``N(u) . + N(.) u``; ``False``:
            Picard (Oseen) matrix ``N(u)``.
        out : ndarray, optional
            Where to write the values (float, C-contiguous, one per entry of the
            pattern; overwritten); a new array by default.
        """
        from .convection_numba import convection_jacobian

        if out is None:
            out = np.zeros(self._indices.size)
        else:
            if (out.shape != self._indices.shape or out.dtype != float
                    or not out.flags.c_contiguous):
                raise ValueError(f"out: shape {out.shape}, dtype {out.dtype}; expected a "
                                 f"C-contiguous float array of shape ({self._indices.size},) "
                                 "(one value per entry of the pattern)")
            out[:] = 0.0
        convection_jacobian(self._velocity("u", u), bool(newton), self._edofs_e,
                            self._maps, *self._reference, self.slot, out)
        return out
