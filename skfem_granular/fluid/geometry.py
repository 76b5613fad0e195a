"""The Taylor-Hood blocks of a moved mesh, from reference-element data.

On a mesh whose vertices move (ALE) the connectivity, the DOF numbering and
the sparsity patterns stay; only the affine maps of the triangles change.
:class:`ReferenceBlocks` keeps the reference-element integrals of the P2/P1
basis functions and the scatter maps into the fixed patterns, and builds
``M``, ``K`` (both viscous forms), ``B`` and the affine maps the convection
kernel takes for new vertex positions in one compiled pass over the triangles
(:mod:`~skfem_granular.fluid.geometry_numba`): on a triangle with map
``x = A xhat + b``,

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

import copy

import numpy as np
import scipy.sparse as sp
from skfem import ElementTriP1, ElementTriP2


def with_data(template: sp.csr_matrix, data: np.ndarray) -> sp.csr_matrix:
    """A CSR matrix on ``template``'s pattern (its index arrays shared) with values ``data``.

    A shallow copy of ``template`` with ``data`` in place of its values: the blocks of a
    moved mesh are rebuilt every step on patterns that never change, and scipy's
    constructor checks the index arrays each time (about 20 us; this takes 4 us).
    """
    if data.shape != template.indices.shape:
        raise ValueError(f"data: {data.shape} values for a pattern of {template.indices.shape}")
    out = copy.copy(template)
    out.data = data
    return out


def scatter_pattern(rows: np.ndarray, cols: np.ndarray, shape: tuple[int, int]
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The CSR pattern of element matrices scattered to ``(rows, cols)`` (any shape).

    Returns
    -------
    slot : int32 ndarray
        Value slot of each local entry (``rows.ravel()`` order).
    indices, indptr : int32 ndarray
        The pattern, rows sorted, no duplicates.
    """
    from .pattern_numba import csr_pattern

    # two counting sorts (compiled): the arrays numpy.unique of the keys
    # rows * ncols + cols with return_inverse gives, in O(n); 32-bit slots halve what
    # the compiled assembly reads (the patterns stay far below 2^31)
    return csr_pattern(np.ascontiguousarray(rows).ravel(), np.ascontiguousarray(cols).ravel(),
                       int(shape[0]), int(shape[1]))


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


def _template(indices: np.ndarray, indptr: np.ndarray, shape: tuple) -> sp.csr_matrix:
    """A CSR matrix of the pattern for :func:`with_data`, with no values of its own.

    Its ``data`` is a placeholder of length 0 (zeros on the velocity pattern would be
    15 MB at 95k DOFs); only :func:`with_data`'s shallow copies carry values.
    """
    T = sp.csr_matrix(shape, dtype=float)  # empty: values of length 0
    T.indices, T.indptr = indices, indptr
    return T


class _Pattern:
    """Fixed CSR pattern of element matrices scattered by ``(rows, cols)`` ``(nel, a, b)``."""

    def __init__(self, rows: np.ndarray | None, cols: np.ndarray | None,
                 shape: tuple[int, int], known: tuple | None = None):
        # ``known``: ``(slot, indices, indptr)`` of the same scatter, built elsewhere
        if known is None:
            assert rows is not None and cols is not None  # the scatter, when not known
            known = scatter_pattern(rows, cols, shape)
        self.slot, self.indices, self.indptr = known
        self.shape = shape
        self._template = _template(self.indices, self.indptr, shape)

    def csr(self, data: np.ndarray) -> sp.csr_matrix:
        """The matrix with values ``data`` on this pattern (index arrays shared)."""
        return with_data(self._template, data)

    def transposed_csr(self, data: np.ndarray) -> sp.csr_matrix:
        """The transpose of :meth:`csr` of ``data``, in CSR format (index arrays shared)."""
        if not hasattr(self, "_transposed_template"):
            indices, indptr, _ = self.transpose_map()
            self._transposed_template = _template(indices, indptr, self.shape[::-1])
        return with_data(self._transposed_template, data[self.transpose_map()[2]])

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
        self.t = np.ascontiguousarray(mesh.t)
        # scikit-fem does not orient triangles: a moved triangle is inverted when its
        # orientation differs from the reference one
        self.orientation = np.sign(affine_maps(mesh.p, mesh.t)[2])
        X, W = space.quadrature
        p2, p1 = ElementTriP2(), ElementTriP1()
        phi = np.array([p2.lbasis(X, i)[0] for i in range(6)])  # (6, nq)
        dphi = np.array([p2.lbasis(X, i)[1] for i in range(6)])  # (6, 2, nq)
        psi = np.array([p1.lbasis(X, i)[0] for i in range(3)])  # (3, nq)
        self.phi, self.dphi, self.weights = phi, dphi, W
        self.Mhat = np.einsum("iq,jq,q->ij", phi, phi, W)
        self.S = np.einsum("ikq,jlq,q->klij", dphi, dphi, W)  # (2, 2, 6, 6)
        self.S4 = np.ascontiguousarray(self.S.reshape(4, 36))
        self.E = np.einsum("mq,jkq,q->kmj", psi, dphi, W)  # (2, 3, 6)
        sdofs = space.scalar_dofs.element_dofs.T  # (nel, 6)
        vdofs = (2 * sdofs[:, :, None] + np.arange(2)).reshape(-1, 12)  # (nel, 12): 2 i + c
        pdofs = space.pressure_dofs.element_dofs.T  # (nel, 3)
        nel = sdofs.shape[0]
        nu, np_ = space.nu, space.np_
        # the velocity pattern is the convection kernel's: entry (e, i, c, j, d) at row
        # 2 edof_i + c, column 2 edof_j + d, in the same order
        self.uu = _Pattern(None, None, (nu, nu), known=space.velocity_pattern)
        self.pu = _Pattern(np.broadcast_to(pdofs[:, :, None], (nel, 3, 12)),
                           np.broadcast_to(vdofs[:, None, :], (nel, 3, 12)), (np_, nu))
        # the pressure mass matrix is |det A| times the reference one per triangle: its
        # values are one sparse product with the triangles' determinants
        self.pp = _Pattern(np.broadcast_to(pdofs[:, :, None], (nel, 3, 3)),
                           np.broadcast_to(pdofs[:, None, :], (nel, 3, 3)), (np_, np_))
        Mhat_p = np.einsum("mq,nq,q->mn", psi, psi, W)
        self._Mp_of_det = sp.csr_matrix(
            (np.tile(Mhat_p.ravel(), nel), (self.pp.slot, np.repeat(np.arange(nel), 9))),
            shape=(self.pp.indices.size, nel))

    def moved(self, p: np.ndarray, check: bool = True,
              parts=("M", "K_symmetric", "K_laplace", "B", "convection")) -> dict:
        """The geometric data ``parts`` of the mesh at ``p``, in one compiled pass over the
        triangles.

        Parameters
        ----------
        p : (2, nv) ndarray
            Vertex positions.
        check : bool
            Check first that no triangle is inverted (skip when already checked).
        parts : sequence of str
            Of ``M``, ``K_symmetric``, ``K_laplace``, ``B`` (CSR on the reference
            patterns; the velocity blocks share one pattern) and ``convection``: the
            triangles' affine maps ``maps`` ``(nel, 5)`` that
            :class:`~skfem_granular.fluid.convection.ConvectionKernel` takes.

        Returns
        -------
        dict
            The blocks by name, and ``maps`` for ``convection``.

        Raises
        ------
        ValueError
            When ``check`` and a triangle is inverted or degenerate at ``p``.
        """
        from .geometry_numba import moved_element_data

        p = np.ascontiguousarray(p, dtype=float)
        if check:
            self.check(p)
        uu, pu = self.uu, self.pu
        n = uu.indices.size
        M, Ks, Kl = (np.zeros(n if name in parts else 0)
                     for name in ("M", "K_symmetric", "K_laplace"))
        B = np.zeros(pu.indices.size if "B" in parts else 0)
        maps = np.empty((self.t.shape[1] if "convection" in parts else 0, 5))
        moved_element_data(p, self.t, self.orientation, self.Mhat, self.S4, self.E,
                           uu.slot, pu.slot, M, Ks, Kl, B, maps)
        out = {"maps": maps} if maps.shape[0] else {}
        for name, data in (("M", M), ("K_symmetric", Ks), ("K_laplace", Kl)):
            if name in parts:
                out[name] = uu.csr(data)
        if "B" in parts:
            out["B"] = pu.csr(B)
        return out

    def pressure_mass(self, p: np.ndarray) -> sp.csr_matrix:
        """The P1 pressure mass matrix of the mesh at ``p`` (no check for inverted
        triangles: ``p`` is a moved space's, checked when it was made)."""
        return self.pp.csr(self._Mp_of_det @ self._oriented_dets(p))

    def _oriented_dets(self, p: np.ndarray) -> np.ndarray:
        """``det A`` of every triangle at ``p`` times its reference orientation (``> 0``:
        valid, ``|det A|``)."""
        t = self.t
        x, y = p[0], p[1]
        x0, y0 = x[t[0]], y[t[0]]
        det = ((x[t[1]] - x0) * (y[t[2]] - y0) - (x[t[2]] - x0) * (y[t[1]] - y0))
        return det * self.orientation

    def check(self, p: np.ndarray) -> None:
        """Raise when a triangle is inverted (orientation changed) or degenerate at ``p``
        (signed determinants only; :meth:`moved` with ``"convection"`` gives the maps).

        Raises
        ------
        ValueError
            Naming the triangle and its signed area.
        """
        det = self._oriented_dets(p)
        if not np.all(det > 0):
            k = int(np.argmin(det))
            raise ValueError(f"mesh motion: triangle {k} is inverted or degenerate "
                             f"(signed area {det[k] / 2:.3g}); remesh before moving this far")
