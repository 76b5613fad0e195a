"""Index maps that turn a saddle-point matrix of a fixed pattern into SuperLU's input.

Every factorisation by :class:`~skfem_granular.fluid.linsolve.SuperLUSolver`
scales the pressure unknowns, subtracts the static-pivoting regularisation
``delta Mp`` and permutes the matrix symmetrically by the mesh's ordering.
On a fixed mesh the pattern never changes (the Newton matrices of
:meth:`~skfem_granular.fluid.operator.NavierStokesOperator.reduced_jacobian`
even share their index arrays), so all of that is a few gathers of the
values through maps built once: :class:`FactorPlan`. Measured at 77k
unknowns: 0.08 s of sparse format conversions per factorisation saved.

Plans are cached by the memory address of the index arrays (for as long as
those arrays live: an entry goes with its pattern, before the address can be
recycled), built the second time a pattern is seen: matrices assembled anew for
each factorisation (a coupled system's) never pay for a plan they would not
reuse. The cache is shared by the threads of a process (a study's thread pool)
and guarded by a lock.
"""

from __future__ import annotations

import threading
import weakref
from collections import OrderedDict

import numpy as np
import scipy.sparse as sp

_CACHE: OrderedDict = OrderedDict()
_SEEN: OrderedDict = OrderedDict()
_CACHE_SIZE = 2
#: guards both tables; re-entrant, as a dropped pattern's callback may run inside
_LOCK = threading.RLock()


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
        # the regularisation touches the pressure block only: its positions and values
        # (a gather over every entry would be 10 MB at 95k DOFs)
        self.reg_at = np.flatnonzero(r > 0).astype(index)
        self.reg_from = (r[self.reg_at] - 1).astype(index)

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
        data = np.append(scaled, 0.0)[self.gather_a]
        data[self.reg_at] -= reg * self.reg_values[self.reg_from]
        return sp.csc_matrix((data, self.ct_indices, self.ct_indptr), shape=(self.n, self.n))


def _owner(a: np.ndarray) -> np.ndarray:
    """The array that owns ``a``'s memory (scipy wraps index arrays in new views)."""
    while isinstance(a.base, np.ndarray):
        a = a.base
    return a


def _address(a: np.ndarray) -> tuple:
    """Where an array's values live, how many and of which type."""
    return (a.__array_interface__["data"][0], a.size, a.dtype.str)


def _remember(table: OrderedDict, key: tuple, value, arrays, size: int) -> None:
    """``table[key] = value`` for as long as the owners of ``arrays`` live.

    The owners are referenced weakly: a pattern that is dropped takes its entry along
    (before its memory can be reused, so addresses stay unique) instead of being kept
    alive by the cache (the Stokes matrix of a steady solve: 10 MB at 95k DOFs).
    """
    def forget(_ref, table=table, key=key):
        with _LOCK:
            table.pop(key, None)

    with _LOCK:
        table[key] = (value, [weakref.ref(_owner(a), forget) for a in arrays])
        while len(table) > size:
            table.popitem(last=False)


def plan_for(A: sp.csr_matrix, nu: int, perm: np.ndarray, Mp=None) -> FactorPlan | None:
    """The cached plan of ``A``'s pattern, or None (first sight, or not usable).

    Keys are the memory addresses of ``A.indptr``, ``A.indices`` and ``perm``,
    plus ``nu`` and the pattern of ``Mp``.
    """
    mp_key = None
    if Mp is not None:
        Mc = sp.csr_matrix(Mp)
        mp_key = (Mc.shape, Mc.nnz, hash(Mc.indices.tobytes()), hash(Mc.indptr.tobytes()))
    arrays = (A.indptr, A.indices, perm)
    key = tuple(_address(a) for a in arrays) + (nu, mp_key)
    with _LOCK:
        entry = _CACHE.get(key)
        if entry is not None:
            _CACHE.move_to_end(key)
            return entry[0]
        if key not in _SEEN:  # first sight: remember, no plan yet
            _remember(_SEEN, key, None, arrays, 4 * _CACHE_SIZE)
            return None
    if not A.has_canonical_format:
        return None
    plan = FactorPlan(A.indptr, A.indices, nu, perm, Mp)
    if not plan.usable:
        return None
    _remember(_CACHE, key, plan, arrays, _CACHE_SIZE)
    return plan
