"""Compiled construction of the sparsity patterns a new mesh needs (one pass each).

A remesh builds the CSR patterns of the Taylor-Hood blocks and the maps that scatter
element matrices into them. Sorting every element entry's ``(row, column)`` key
(``numpy.unique``) costs ``O(n log n)`` and a few arrays of ``n`` 64-bit keys; these
kernels give the same arrays with two counting sorts (``O(n)``), which matters at a
million unknowns, where a remesh built its patterns in seconds.

- :func:`csr_pattern`: the pattern of entries scattered to ``(rows, cols)`` and each
  entry's value slot, as ``numpy.unique`` of the keys ``rows * ncols + cols`` with
  ``return_inverse`` gives them;
- :func:`vector_pattern`: the pattern of a 2-component P2 field's element matrices
  from the scalar one (:func:`~skfem_granular.fluid.convection.element_pattern`);
- :func:`positions_in`: where the entries of one sorted pattern sit in a wider one;
- :func:`add_at_positions`: one pattern's values added into the wider one's there.

Compiled with numba at the first call (:func:`~skfem_granular._jit.lazy_njit`,
``cache=True``).
"""

from __future__ import annotations

import numpy as np

from .._jit import lazy_njit


@lazy_njit  # numba.njit(cache=True) at the first call
def csr_pattern(rows, cols, nrows, ncols):  # pragma: no cover (compiled)
    """The CSR pattern of the entries ``(rows[k], cols[k])`` and each entry's slot in it.

    Parameters
    ----------
    rows, cols : (n,) integer ndarray
        Row and column of every entry (duplicates allowed), within ``nrows``, ``ncols``.
    nrows, ncols : int
        Shape of the matrix.

    Returns
    -------
    slot : (n,) int32 ndarray
        Position of entry ``k`` in ``indices`` (equal entries share it).
    indices : (nnz,) int32 ndarray
        Column of every distinct entry, rows in order, columns sorted within a row.
    indptr : (nrows + 1,) int32 ndarray
        Row pointers.
    """
    n = rows.size
    # a counting sort by column, then a stable one by row: entries in (row, column) order
    order = _stable_by(rows, nrows, _stable_by(cols, ncols, np.arange(n)))
    slot = np.empty(n, dtype=np.int32)
    indices = np.empty(n, dtype=np.int32)
    counts = np.zeros(nrows + 1, dtype=np.int64)
    nnz = 0
    last_r = -1
    last_c = -1
    for m in range(n):
        k = order[m]
        r = rows[k]
        c = cols[k]
        if r != last_r or c != last_c:
            indices[nnz] = c
            nnz += 1
            counts[r + 1] += 1
            last_r = r
            last_c = c
        slot[k] = nnz - 1
    indptr = np.empty(nrows + 1, dtype=np.int32)
    total = 0
    for r in range(nrows + 1):
        total += counts[r]
        indptr[r] = total
    return slot, indices[:nnz].copy(), indptr


@lazy_njit
def _stable_by(keys, nkeys, order):  # pragma: no cover (compiled)
    """``order`` (entry numbers) stably sorted by ``keys`` of the entries, ``0 <= keys <
    nkeys``: a counting sort."""
    start = np.zeros(nkeys + 1, dtype=np.int64)
    for m in range(order.size):
        start[keys[order[m]] + 1] += 1
    for c in range(nkeys):
        start[c + 1] += start[c]
    out = np.empty(order.size, dtype=np.int64)
    for m in range(order.size):
        k = order[m]
        c = keys[k]
        out[start[c]] = k
        start[c] += 1
    return out


@lazy_njit
def vector_pattern(edofs, sslot, sind, sptr):  # pragma: no cover (compiled)
    """The pattern of the 12 x 12 element matrices of a 2-component P2 field.

    Vector DOF ``2 k + c`` is component ``c`` of scalar DOF ``k``; row ``2 k + c`` holds
    columns ``2 j, 2 j + 1`` for each column ``j`` of scalar row ``k``, in order.

    Parameters
    ----------
    edofs : (nel, nloc) integer ndarray
        Scalar DOFs of every element.
    sslot, sind, sptr : ndarray
        The scalar pattern (:func:`csr_pattern` of the ``nloc x nloc`` couplings, entry
        ``(e, i, j)`` at ``e * nloc**2 + i * nloc + j``).

    Returns
    -------
    slot : (nel * 4 nloc**2,) int32 ndarray
        Value slot of local entry ``(e, i, c, j, d)`` (row ``2 edofs[e, i] + c``, column
        ``2 edofs[e, j] + d``), in that order.
    indices, indptr : int32 ndarray
        The pattern.
    """
    nel, nloc = edofs.shape
    ns = sptr.size - 1
    indptr = np.empty(2 * ns + 1, dtype=np.int64)
    for k in range(ns):
        indptr[2 * k] = 4 * np.int64(sptr[k])
        indptr[2 * k + 1] = 4 * np.int64(sptr[k]) + 2 * (np.int64(sptr[k + 1]) - sptr[k])
    indptr[2 * ns] = 4 * np.int64(sptr[ns])
    indices = np.empty(indptr[2 * ns], dtype=np.int32)
    for k in range(ns):
        for c in range(2):
            base = indptr[2 * k + c] - 2 * np.int64(sptr[k])
            for m in range(sptr[k], sptr[k + 1]):
                indices[base + 2 * m] = 2 * sind[m]
                indices[base + 2 * m + 1] = 2 * sind[m] + 1
    slot = np.empty(nel * 4 * nloc * nloc, dtype=np.int32)
    q = 0
    for e in range(nel):
        for i in range(nloc):
            k = edofs[e, i]
            for c in range(2):
                row = indptr[2 * k + c] - 2 * np.int64(sptr[k])
                for j in range(nloc):
                    s = row + 2 * np.int64(sslot[(e * nloc + i) * nloc + j])
                    slot[q] = s
                    slot[q + 1] = s + 1
                    q += 2
    return slot, indices, indptr.astype(np.int32)


@lazy_njit
def positions_in(indptr_n, indices_n, indptr_a, indices_a, pos):  # pragma: no cover
    """Write into ``pos`` where each entry of pattern ``a`` sits in pattern ``n``.

    Both patterns have the same rows and sorted columns within a row. Returns False
    (``pos`` then incomplete) when an entry of ``a`` is not in ``n``.
    """
    nrows = indptr_a.size - 1
    for r in range(nrows):
        q = indptr_n[r]
        end = indptr_n[r + 1]
        for m in range(indptr_a[r], indptr_a[r + 1]):
            c = indices_a[m]
            while q < end and indices_n[q] < c:
                q += 1
            if q == end or indices_n[q] != c:
                return False
            pos[m] = q
    return True


@lazy_njit
def stack_saddle(a_data, a_ind, a_ptr, b_data, b_ind, b_ptr, shift,
                 c_data, c_ind, c_ptr):  # pragma: no cover (compiled)
    """CSR arrays of ``[[A, B], [C]]``: row ``i`` of ``A`` followed by row ``i`` of ``B``
    (columns shifted by ``shift``), then the rows of ``C`` (as wide as the whole).

    Every row's entries in stored order, as ``scipy.sparse.hstack`` and ``vstack`` of CSR
    blocks give them. Returns ``(data, indices, indptr)``, ``indptr`` int64.
    """
    na = a_ptr.size - 1
    nc = c_ptr.size - 1
    nnz = (a_ptr[na] - a_ptr[0]) + (b_ptr[na] - b_ptr[0]) + (c_ptr[nc] - c_ptr[0])
    data = np.empty(nnz, dtype=np.float64)
    indices = np.empty(nnz, dtype=np.int32)
    indptr = np.empty(na + nc + 1, dtype=np.int64)
    q = 0
    for i in range(na):
        indptr[i] = q
        for m in range(a_ptr[i], a_ptr[i + 1]):
            data[q] = a_data[m]
            indices[q] = a_ind[m]
            q += 1
        for m in range(b_ptr[i], b_ptr[i + 1]):
            data[q] = b_data[m]
            indices[q] = b_ind[m] + shift
            q += 1
    for i in range(nc):
        indptr[na + i] = q
        for m in range(c_ptr[i], c_ptr[i + 1]):
            data[q] = c_data[m]
            indices[q] = c_ind[m]
            q += 1
    indptr[na + nc] = q
    return data, indices, indptr


@lazy_njit
def add_at_positions(wide, pos, values):  # pragma: no cover (compiled)
    """``wide[pos] = values + wide[pos]`` in place, for distinct ``pos`` (one pass; the
    same sums as numpy's gather, add and scatter, without their two temporaries)."""
    for k in range(pos.size):
        wide[pos[k]] = values[k] + wide[pos[k]]

