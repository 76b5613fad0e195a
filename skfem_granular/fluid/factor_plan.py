"""Index maps that turn a saddle-point matrix of a fixed pattern into SuperLU's input.

Every factorisation by :class:`~skfem_granular.fluid.linsolve.SuperLUSolver`
scales the pressure unknowns, subtracts the static-pivoting regularisation
``delta Mp`` and permutes the matrix symmetrically by the mesh's ordering.
On a fixed mesh the pattern never changes (the Newton matrices of
:meth:`~skfem_granular.fluid.operator.NavierStokesOperator.reduced_jacobian`
even share their index arrays), so all of that is a few gathers of the
values through maps built once: :class:`FactorPlan`. Measured at 77k
unknowns: 0.08 s of sparse format conversions per factorisation saved.

Plans are cached by the memory address of the index arrays (kept alive by
the cache, so addresses are not recycled), built the second time a pattern
is seen: matrices assembled anew for each factorisation (a coupled
system's) never pay for a plan they would not reuse.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np
import scipy.sparse as sp

_CACHE: OrderedDict = OrderedDict()
_SEEN: OrderedDict = OrderedDict()
_CACHE_SIZE = 2


class FactorPlan:
    """Maps from the values of ``A`` (CSR, fixed pattern) to SuperLU's CSC input.

    SuperLU factorises ``(P (D A D - reg) P^T)^T``: its CSC arrays are the
    CSR arrays of the permuted matrix, so no format conversion is needed.

    Parameters
    ----------
    indptr, indices : ndarray
        CSR pattern of ``A`` (``n x n``, canonical).
    nu : int
        Velocity unknowns (the rest are pressures).
    perm : ndarray
        Symmetric permutation (row ``i`` of the permuted matrix is row ``perm[i]``).
    Mp : sparse matrix or None
        Pressure mass matrix on the free pressures (pattern of the
        regularisation), or None for a diagonal one.
    """

    def __init__(self, indptr, indices, nu: int, perm: np.ndarray, Mp=None):
        # temporaries are dropped as soon as they are used: the plan is built right before
        # a factorisation, whose factors would otherwise land on top of them (95k DOFs:
        # the build raised the peak of a steady solve by 140 MB)
        n = indptr.size - 1
        nnz = indices.size
        rows = np.repeat(np.arange(n, dtype=np.int32 if n < 2**31 - 1 else np.int64),
                         np.diff(indptr))
        cols = indices
        self.n, self.nu, self.nnz = n, nu, nnz
        self.klass = ((rows >= nu).astype(np.int8) + (cols >= nu).astype(np.int8))
        self.upper_right = np.flatnonzero((rows < nu) & (cols >= nu))
        diag = np.flatnonzero((rows == cols) & (rows < nu))
        del rows
        self.usable = diag.size == nu  # every velocity row holds its diagonal
        self.diag_u = diag
        # regularisation pattern, values normalised to max 1
        if Mp is None:
            r_rows = r_cols = np.arange(nu, n, dtype=np.int64)
            r_vals = np.ones(n - nu)
        else:
            Mc = sp.coo_matrix(Mp)
            r_rows, r_cols = nu + Mc.row.astype(np.int64), nu + Mc.col.astype(np.int64)
            r_vals = Mc.data / np.abs(Mc.data).max()
        self.reg_values = r_vals
        # union pattern: ids of A's entries and the regularisation's entries, decoded from
        # one exact float sum (ids below 2^53)
        base = float(nnz + 1)
        U = (sp.csr_matrix((np.arange(1, nnz + 1, dtype=float), indices, indptr), shape=(n, n))
             + sp.csr_matrix((base * np.arange(1, r_vals.size + 1, dtype=float),
                              (r_rows, r_cols)), shape=(n, n))).tocsr()
        U.sort_indices()
        index = np.int32 if max(nnz, r_vals.size, U.nnz) < 2**31 - 1 else np.int64
        a_id = np.rint(U.data % base).astype(index)  # 0: no entry of A here
        r_id = np.rint(U.data // base).astype(index)  # 0: no regularisation here
        # the permuted transpose: gather rows, relabel columns, sort
        U.data = np.arange(1, U.nnz + 1, dtype=float)
        P = U[perm]
        del U
        inv = np.empty_like(perm)
        inv[perm] = np.arange(n)
        CT = sp.csc_matrix((P.data, inv[P.indices].astype(P.indices.dtype), P.indptr),
                           shape=(n, n))
        del P
        CT.sort_indices()
        src = np.rint(CT.data).astype(index) - 1  # position in U of each CT entry
        self.ct_indices, self.ct_indptr = CT.indices, CT.indptr
        del CT
        # 32-bit gathers (patterns stay far below 2^31 entries): 10 MB less per plan at 95k
        a, r = a_id[src], r_id[src]
        del a_id, r_id, src
        self.gather_a = np.where(a > 0, a - 1, nnz).astype(index)  # nnz: the zero slot
        self.gather_r = np.where(r > 0, r - 1, r_vals.size).astype(index)

    def scale(self, data: np.ndarray) -> tuple[float, np.ndarray, float]:
        """Pressure scale ``s``, the values of ``D A D`` and the median velocity pivot."""
        dabs = np.abs(data[self.diag_u])
        pos = dabs[dabs > 0]
        bmax = np.abs(data[self.upper_right]).max() if self.upper_right.size else 1.0
        s = float(np.median(pos) / bmax) if pos.size and bmax > 0 else 1.0
        scaled = data * np.array([1.0, s, s * s])[self.klass]
        return s, scaled, float(np.median(dabs))

    def permuted_transpose(self, scaled: np.ndarray, reg: float) -> sp.csc_matrix:
        """CSC arrays of ``(P (scaled - reg * Mp) P^T)^T`` for SuperLU."""
        ext_a = np.append(scaled, 0.0)
        ext_r = np.append(reg * self.reg_values, 0.0)
        data = ext_a[self.gather_a] - ext_r[self.gather_r]
        return sp.csc_matrix((data, self.ct_indices, self.ct_indptr), shape=(self.n, self.n))


def _address(a: np.ndarray) -> tuple:
    """Where an array's values live, how many and of which type."""
    return (a.__array_interface__["data"][0], a.size, a.dtype.str)


def plan_for(A: sp.csr_matrix, nu: int, perm: np.ndarray, Mp=None) -> FactorPlan | None:
    """The cached plan of ``A``'s pattern, or None (first sight, or not usable).

    Keys are the memory addresses of ``A.indptr``, ``A.indices`` and ``perm``
    (scipy wraps index arrays it is given in new views of the same memory), plus
    ``nu`` and the pattern of ``Mp``.
    """
    mp_key = None
    if Mp is not None:
        Mc = sp.csr_matrix(Mp)
        mp_key = (Mc.shape, Mc.nnz, hash(Mc.indices.tobytes()), hash(Mc.indptr.tobytes()))
    key = (_address(A.indptr), _address(A.indices), _address(perm), nu, mp_key)
    entry = _CACHE.get(key)
    if entry is not None:
        _CACHE.move_to_end(key)
        return entry[0]
    if key not in _SEEN:  # first sight: remember, no plan yet
        _SEEN[key] = (A.indptr, A.indices, perm)
        while len(_SEEN) > 4 * _CACHE_SIZE:
            _SEEN.popitem(last=False)
        return None
    if not A.has_canonical_format:
        return None
    plan = FactorPlan(A.indptr, A.indices, nu, perm, Mp)
    if not plan.usable:
        return None
    _CACHE[key] = (plan, A.indptr, A.indices, perm)  # references keep the ids unique
    while len(_CACHE) > _CACHE_SIZE:
        _CACHE.popitem(last=False)
    return plan
