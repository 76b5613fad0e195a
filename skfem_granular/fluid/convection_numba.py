"""Compiled convection vectors (one pass over the triangles).

:func:`convection_vector` is the kernel behind
:meth:`~skfem_granular.fluid.convection.ConvectionKernel.apply` and
:meth:`~skfem_granular.fluid.convection.ConvectionKernel.apply_relative`: for every
triangle it gathers the local DOFs, evaluates the wind and the field's gradient at the
quadrature points from the kernel's element tables and adds ``((wind . grad) b, v_i)``
into the global vector. The formulas are those of the numpy version in
:mod:`~skfem_granular.fluid.convection`; the element vectors are added in the element
order of its ``numpy.bincount`` scatter, so only the per-element sums are ordered
differently (round-off).

Compiled with numba at the first call (:func:`~skfem_granular._jit.lazy_njit`,
``cache=True``).
"""

from __future__ import annotations

import numpy as np

from .._jit import lazy_njit


@lazy_njit  # numba.njit(cache=True) at the first call
def convection_vector(a, ca, w, cw, b, edofs, tab, wphi, out):  # pragma: no cover (compiled)
    """Add ``(((ca a - cw w) . grad) b, v_i)`` for every test function ``v_i`` to ``out``.

    Parameters
    ----------
    a, w, b : (nu,) ndarray
        P2 vector fields (DOF ``2 k + c`` is component ``c`` of node ``k``): the wind is
        ``ca a - cw w``, the advected field ``b``.
    ca, cw : float
        Coefficients of the wind (``cw = 0`` skips ``w``).
    edofs : (nel, 6) int ndarray
        Scalar P2 DOFs of every triangle.
    tab : (nel, 3 nq, 6) ndarray
        Basis values, x- and y-derivatives at the quadrature points.
    wphi : (nel, 6, nq) ndarray
        ``phi_i(q) dx(q)``.
    out : (nu,) ndarray
        Accumulated into.
    """
    nel = edofs.shape[0]
    nq = wphi.shape[2]
    la = np.empty((6, 2))
    lb = np.empty((6, 2))
    adv = np.empty((nq, 2))
    for e in range(nel):
        for i in range(6):
            k = edofs[e, i]
            for c in range(2):
                la[i, c] = ca * a[2 * k + c]
                if cw != 0.0:
                    la[i, c] -= cw * w[2 * k + c]
                lb[i, c] = b[2 * k + c]
        for q in range(nq):
            wx = 0.0
            wy = 0.0
            bx0 = 0.0
            bx1 = 0.0
            by0 = 0.0
            by1 = 0.0
            for i in range(6):
                v = tab[e, q, i]
                dx = tab[e, nq + q, i]
                dy = tab[e, 2 * nq + q, i]
                wx += v * la[i, 0]
                wy += v * la[i, 1]
                bx0 += dx * lb[i, 0]
                bx1 += dx * lb[i, 1]
                by0 += dy * lb[i, 0]
                by1 += dy * lb[i, 1]
            adv[q, 0] = bx0 * wx + by0 * wy
            adv[q, 1] = bx1 * wx + by1 * wy
        for i in range(6):
            k = edofs[e, i]
            for c in range(2):
                s = 0.0
                for q in range(nq):
                    s += wphi[e, i, q] * adv[q, c]
                out[2 * k + c] += s
