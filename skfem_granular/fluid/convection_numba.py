"""Compiled convection vectors and Jacobians (one pass over the triangles each).

:func:`convection_vector` is the kernel behind
:meth:`~skfem_granular.fluid.convection.ConvectionKernel.apply` and
:meth:`~skfem_granular.fluid.convection.ConvectionKernel.apply_relative`: for every
triangle it gathers the local DOFs, evaluates the wind and the field's gradient at the
quadrature points and adds ``((wind . grad) b, v_i)`` into the global vector.
:func:`convection_jacobian` adds the element matrices of the linearised term into the
values of the kernel's fixed pattern
(:meth:`~skfem_granular.fluid.convection.ConvectionKernel.jacobian_data`).

Both take the triangles' affine maps, five numbers each (``maps[e] = (Ainv[0, 0],
Ainv[1, 0], Ainv[0, 1], Ainv[1, 1], |det A|)``), and the reference element's basis
values, gradients and quadrature weights, and form the basis gradients and weighted
values of a triangle as they go (:func:`_element_basis`), by the formulas of
:func:`~skfem_granular.fluid.geometry_numba.moved_element_data`: tables of them for
every triangle would be 27 MB at 95k DOFs.

Compiled with numba at the first call (:func:`~skfem_granular._jit.lazy_njit`,
``cache=True``).
"""

from __future__ import annotations

import numpy as np

from .._jit import lazy_njit


@lazy_njit  # numba.njit(cache=True) at the first call
def _element_basis(maps, e, phi, dref, weights, gx, gy, wphi):  # pragma: no cover (compiled)
    """x- and y-derivatives ``gx``, ``gy`` ``(nq, 6)`` and ``wphi`` ``(6, nq)``
    (``phi_i(q) dx(q)``) of the P2 basis on triangle ``e``."""
    # maps[e] = (Ainv[0, 0], Ainv[1, 0], Ainv[0, 1], Ainv[1, 1], |det A|): the rows of
    # Ainv^T, which takes reference gradients to physical ones
    i00, i10, i01, i11, det = maps[e, 0], maps[e, 1], maps[e, 2], maps[e, 3], maps[e, 4]
    for q in range(weights.shape[0]):
        dxq = det * weights[q]
        for i in range(6):
            gx[q, i] = i00 * dref[i, 0, q] + i10 * dref[i, 1, q]
            gy[q, i] = i01 * dref[i, 0, q] + i11 * dref[i, 1, q]
            wphi[i, q] = phi[i, q] * dxq


@lazy_njit  # numba.njit(cache=True) at the first call
def convection_vector(a, ca, w, cw, b, edofs, maps, phi, dref, weights,
                      out):  # pragma: no cover (compiled)
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
    maps : (nel, 5) ndarray
        ``Ainv[0, 0], Ainv[1, 0], Ainv[0, 1], Ainv[1, 1], |det A|`` of every triangle.
    phi : (6, nq) ndarray
        Basis values at the quadrature points.
    dref : (6, 2, nq) ndarray
        Reference gradients of the basis at the quadrature points.
    weights : (nq,) ndarray
        Reference quadrature weights.
    out : (nu,) ndarray
        Accumulated into.
    """
    nel = edofs.shape[0]
    nq = weights.shape[0]
    la = np.empty((6, 2))
    lb = np.empty((6, 2))
    adv = np.empty((nq, 2))
    gx = np.empty((nq, 6))
    gy = np.empty((nq, 6))
    wphi = np.empty((6, nq))
    for e in range(nel):
        _element_basis(maps, e, phi, dref, weights, gx, gy, wphi)
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
                v = phi[i, q]
                dx = gx[q, i]
                dy = gy[q, i]
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
                    s += wphi[i, q] * adv[q, c]
                out[2 * k + c] += s


@lazy_njit  # numba.njit(cache=True) at the first call
def convection_jacobian(u, newton, edofs, maps, phi, dref, weights, slot,
                        out):  # pragma: no cover (compiled)
    """Add the element matrices of the convection term linearised at ``u`` to ``out``.

    Entry ``(i, c, j, d)`` of a triangle's matrix (row ``2 edof_i + c``, column
    ``2 edof_j + d``) is ``delta_cd (phi_i, u . grad phi_j)``, plus with ``newton``
    ``(phi_i phi_j, d_d u_c)``; it is added at ``out[slot[144 e + 24 i + 12 c + 2 j + d]]``
    (the kernel's pattern), element after element.

    Parameters
    ----------
    u : (nu,) ndarray
        The wind (P2 vector field).
    newton : bool
        Add the term ``N(.) u`` of the full Newton linearisation.
    edofs, maps, phi, dref, weights
        As for :func:`convection_vector`.
    slot : (nel * 144,) int ndarray
        Value slot of every local entry in ``(e, i, c, j, d)`` order.
    out : ndarray
        Values on the pattern, accumulated into.
    """
    nel = edofs.shape[0]
    nq = weights.shape[0]
    lu = np.empty((6, 2))
    grad = np.empty((nq, 2, 2))  # (q, c, d): d_d u_c
    adv = np.empty((nq, 6))  # (u . grad) phi_j at q
    gx = np.empty((nq, 6))
    gy = np.empty((nq, 6))
    wphi = np.empty((6, nq))
    for e in range(nel):
        _element_basis(maps, e, phi, dref, weights, gx, gy, wphi)
        for i in range(6):
            k = edofs[e, i]
            lu[i, 0] = u[2 * k]
            lu[i, 1] = u[2 * k + 1]
        for q in range(nq):
            ux = 0.0
            uy = 0.0
            g00 = 0.0
            g01 = 0.0
            g10 = 0.0
            g11 = 0.0
            for i in range(6):
                v = phi[i, q]
                dx = gx[q, i]
                dy = gy[q, i]
                ux += v * lu[i, 0]
                uy += v * lu[i, 1]
                g00 += dx * lu[i, 0]
                g01 += dy * lu[i, 0]
                g10 += dx * lu[i, 1]
                g11 += dy * lu[i, 1]
            grad[q, 0, 0] = g00
            grad[q, 0, 1] = g01
            grad[q, 1, 0] = g10
            grad[q, 1, 1] = g11
            for j in range(6):
                adv[q, j] = gx[q, j] * ux + gy[q, j] * uy
        base = 144 * e
        for i in range(6):
            for j in range(6):
                t1 = 0.0
                for q in range(nq):
                    t1 += wphi[i, q] * adv[q, j]
                for c in range(2):
                    for d in range(2):
                        s = 0.0
                        if newton:
                            for q in range(nq):
                                s += wphi[i, q] * phi[j, q] * grad[q, c, d]
                        if c == d:
                            s += t1
                        out[slot[base + 24 * i + 12 * c + 2 * j + d]] += s
