"""SuperLU's input for a saddle-point matrix seen once, in compiled passes.

A factorisation on a new mesh (or of a new coupled system) scales the pressure
unknowns, subtracts the static-pivoting regularisation and permutes the matrix
symmetrically, then hands SuperLU the transpose in CSC form
(:class:`~skfem_granular.fluid.superlu.SuperLUSolver`). Through scipy that is a
scaled copy, a sparse difference, a row gather and an index sort, each a pass over
tens of millions of entries at 1000 grains; :func:`permuted_transpose` does it in
three passes over the entries, with the same arithmetic (``(d_i a_ij) d_j``, then
minus the regularisation, exact zeros dropped), so the factors are the same bit for
bit. Compiled with numba at the first call (:func:`~skfem_granular._jit.lazy_njit`).
"""

from __future__ import annotations

import numpy as np

from .._jit import lazy_njit


@lazy_njit  # numba.njit(cache=True) at the first call
def upper_right_max(data, indices, indptr, nu):  # pragma: no cover (compiled)
    """``max |a_ij|`` over the entries with ``i < nu <= j`` (the ``B^T`` block), or -1.0
    when there are none."""
    best = -1.0
    for i in range(min(nu, indptr.size - 1)):
        for m in range(indptr[i], indptr[i + 1]):
            if indices[m] >= nu:
                v = abs(data[m])
                if v > best:
                    best = v
    return best


@lazy_njit
def permuted_transpose(data, indices, indptr, scale, rdata, rindices, rindptr,
                       perm, inv):  # pragma: no cover (compiled)
    """CSC arrays of ``(P (D A D - R) P^T)^T`` with sorted row indices.

    Parameters
    ----------
    data, indices, indptr : ndarray
        ``A`` in canonical CSR (sorted columns, no duplicates), ``n x n``.
    scale : (n,) ndarray
        The diagonal of ``D``.
    rdata, rindices, rindptr : ndarray
        ``R`` in canonical CSR, ``n x n``.
    perm, inv : (n,) integer ndarray
        Row ``i`` of the permuted matrix is row ``perm[i]``; ``inv[perm[i]] = i``.

    Returns
    -------
    out_indptr : int64 ndarray
    out_indices : int32 ndarray
        The CSC pattern.
    out_data : ndarray
        Its values: ``(d_i a_ij) d_j - r_ij`` where both exist, ``(d_i a_ij) d_j`` or
        ``-r_ij`` where one does, exact zeros left out.
    """
    n = indptr.size - 1
    # pass 1: the rows of D A D - R in A's row order, columns relabelled by inv
    count = np.zeros(n + 1, dtype=np.int64)
    for r in range(n):
        a, a_end = indptr[r], indptr[r + 1]
        b, b_end = rindptr[r], rindptr[r + 1]
        k = 0
        while a < a_end or b < b_end:
            ca = indices[a] if a < a_end else n
            cb = rindices[b] if b < b_end else n
            if ca < cb:
                v = (scale[r] * data[a]) * scale[ca]
                a += 1
            elif cb < ca:
                v = -rdata[b]
                b += 1
            else:
                v = (scale[r] * data[a]) * scale[ca]
                if v != 0.0:
                    v = v - rdata[b]
                else:
                    v = -rdata[b]
                a += 1
                b += 1
            if v != 0.0:
                k += 1
        count[r + 1] = k
    for r in range(n):
        count[r + 1] += count[r]
    nnz = count[n]
    col = np.empty(nnz, dtype=np.int32)  # n < 2^31 (checked by the caller)
    val = np.empty(nnz, dtype=np.float64)
    for r in range(n):
        a, a_end = indptr[r], indptr[r + 1]
        b, b_end = rindptr[r], rindptr[r + 1]
        q = count[r]
        while a < a_end or b < b_end:
            ca = indices[a] if a < a_end else n
            cb = rindices[b] if b < b_end else n
            if ca < cb:
                c = ca
                v = (scale[r] * data[a]) * scale[ca]
                a += 1
            elif cb < ca:
                c = cb
                v = -rdata[b]
                b += 1
            else:
                c = ca
                v = (scale[r] * data[a]) * scale[ca]
                if v != 0.0:
                    v = v - rdata[b]
                else:
                    v = -rdata[b]
                a += 1
                b += 1
            if v != 0.0:
                col[q] = inv[c]
                val[q] = v
                q += 1
    # pass 2: the rows in the permuted order, bucketed by their relabelled column (a
    # counting sort: within a bucket the permuted rows come in increasing order)
    tptr = np.zeros(n + 1, dtype=np.int64)
    for q in range(nnz):
        tptr[col[q] + 1] += 1
    for i in range(n):
        tptr[i + 1] += tptr[i]
    fill = tptr[:n].copy()
    trow = np.empty(nnz, dtype=np.int32)
    tval = np.empty(nnz, dtype=np.float64)
    for j in range(n):
        r = perm[j]
        for q in range(count[r], count[r + 1]):
            i = col[q]
            trow[fill[i]] = j
            tval[fill[i]] = val[q]
            fill[i] += 1
    # pass 3: back, bucketed by permuted row: row j of P (D A D - R) P^T with its
    # columns in increasing order, which are the CSC arrays of the transpose (into the
    # buffers of pass 1, no longer needed: 24 bytes per entry at the peak, not 36)
    out_ptr = np.zeros(n + 1, dtype=np.int64)
    for j in range(n):
        out_ptr[j + 1] = count[perm[j] + 1] - count[perm[j]]
    for j in range(n):
        out_ptr[j + 1] += out_ptr[j]
    fill = out_ptr[:n].copy()
    for i in range(n):
        for q in range(tptr[i], tptr[i + 1]):
            j = trow[q]
            col[fill[j]] = i
            val[fill[j]] = tval[q]
            fill[j] += 1
    return out_ptr, col, val
