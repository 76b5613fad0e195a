"""Compiled assembly of the geometric blocks of a moved mesh (one pass over the triangles).

:func:`moved_element_data` is the kernel behind
:meth:`~skfem_granular.fluid.geometry.ReferenceBlocks.moved`: for every triangle it
forms the affine map from the vertex positions and adds the element matrices of
``M``, both viscous forms and ``B`` into the values of their fixed CSR patterns, and
writes the affine maps the convection kernel takes (five numbers per triangle). The
formulas are those of :mod:`~skfem_granular.fluid.geometry`; contributions are added
in the element order of the scatter maps, as ``numpy.bincount`` would.

Compiled with numba at the first call (:func:`~skfem_granular._jit.lazy_njit`,
``cache=True``: compiled once per installation and reused by later processes).
"""

from __future__ import annotations

import numpy as np

from .._jit import lazy_njit


@lazy_njit  # numba.njit(cache=True) at the first call
def moved_element_data(p, t, orientation, Mhat, S4, E, uu_slot, pu_slot,
                       M, Ks, Kl, B, maps):  # pragma: no cover (compiled)
    """Accumulate the blocks of the triangles ``t`` at vertex positions ``p``.

    Parameters
    ----------
    p : (2, nv) ndarray
        Vertex positions.
    t : (3, nel) ndarray
        Triangles.
    orientation : (nel,) ndarray
        Sign of each triangle's determinant in the reference mesh.
    Mhat, S4, E : ndarray
        Reference integrals ``(6, 6)``, ``(4, 36)`` (``S[k, l, i, j]`` as ``[2 k + l,
        6 i + j]``), ``(2, 3, 6)``
        (:class:`~skfem_granular.fluid.geometry.ReferenceBlocks`).
    uu_slot : (nel * 144,) ndarray
        Value slot of local velocity entry ``(e, i, c, j, d)``.
    pu_slot : (nel * 36,) ndarray
        Value slot of local divergence entry ``(e, m, j, d)``.
    M, Ks, Kl, B : ndarray
        Zeroed value arrays of the blocks (output): ``M``, the symmetric-gradient and
        the Laplace forms of ``K``, ``B``; one of size 0 is skipped.
    maps : (nel, 5) ndarray
        ``Ainv[0, 0], Ainv[1, 0], Ainv[0, 1], Ainv[1, 1], |det A|`` of every triangle
        (output, for :mod:`~skfem_granular.fluid.convection_numba`; skipped when of
        length 0).
    """
    nel = t.shape[1]
    mass, symmetric, laplace = M.size > 0, Ks.size > 0, Kl.size > 0
    divergence, affine = B.size > 0, maps.shape[0] > 0
    At = np.empty((2, 2))
    G3 = np.empty((3, 36))
    for e in range(nel):
        a, b, c_ = t[0, e], t[1, e], t[2, e]
        a00 = p[0, b] - p[0, a]
        a10 = p[1, b] - p[1, a]
        a01 = p[0, c_] - p[0, a]
        a11 = p[1, c_] - p[1, a]
        det = a00 * a11 - a01 * a10
        # Ainv = [[a11, -a01], [-a10, a00]] / det; At[c, k] = Ainv[k, c]
        At[0, 0] = a11 / det
        At[1, 1] = a00 / det
        At[1, 0] = -a01 / det
        At[0, 1] = -a10 / det
        det = det * orientation[e]  # |det A| of a valid triangle
        base = 144 * e
        if mass:
            for i in range(6):
                for c in range(2):
                    for j in range(6):
                        M[uu_slot[base + ((2 * i + c) * 6 + j) * 2 + c]] += det * Mhat[i, j]
        if symmetric or laplace:
            # G[c, d, i, j] = int d_c phi_i d_d phi_j = sum_kl det At[c, k] At[d, l] S[k, l, i, j]
            # for (c, d) = (0, 0), (0, 1), (1, 1) as rows of G3 ((i, j) flattened);
            # G[1, 0, i, j] = G[0, 1, j, i]
            for r in range(3):
                c, d = r // 2, (r + 1) // 2
                c0 = det * At[c, 0] * At[d, 0]
                c1 = det * At[c, 0] * At[d, 1]
                c2 = det * At[c, 1] * At[d, 0]
                c3 = det * At[c, 1] * At[d, 1]
                for ij in range(36):
                    G3[r, ij] = c0 * S4[0, ij] + c1 * S4[1, ij] + c2 * S4[2, ij] + c3 * S4[3, ij]
            for i in range(6):
                for c in range(2):
                    for j in range(6):
                        ij = 6 * i + j
                        lap = G3[0, ij] + G3[2, ij]
                        row = base + ((2 * i + c) * 6 + j) * 2
                        if laplace:
                            Kl[uu_slot[row + c]] += lap
                        if symmetric:
                            # + int d_d phi_i d_c phi_j at (i, c, j, d): G[d, c, i, j]
                            if c == 0:
                                Ks[uu_slot[row]] += lap + G3[0, ij]
                                Ks[uu_slot[row + 1]] += G3[1, 6 * j + i]
                            else:
                                Ks[uu_slot[row]] += G3[1, ij]
                                Ks[uu_slot[row + 1]] += lap + G3[2, ij]
        if divergence:
            base = 36 * e
            for m in range(3):
                for j in range(6):
                    for d in range(2):
                        s = At[d, 0] * E[0, m, j] + At[d, 1] * E[1, m, j]
                        B[pu_slot[base + (6 * m + j) * 2 + d]] += -(det * s)
        if affine:
            maps[e, 0] = At[0, 0]
            maps[e, 1] = At[0, 1]
            maps[e, 2] = At[1, 0]
            maps[e, 3] = At[1, 1]
            maps[e, 4] = det

