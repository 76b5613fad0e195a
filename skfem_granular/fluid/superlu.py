"""Sparse LU by SuperLU (scipy) with static pivoting and the mesh's ordering."""

from __future__ import annotations

import time
from typing import Protocol

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .. import memory
from .factor_plan import plan_for
from .solver_base import SaddlePointSolver

#: Entries of threshold-pivoted factors per squared unknown, an upper bound. Without static
#: pivots SuperLU leaves the fill-reducing order and its factors of a coupled matrix come
#: close to dense: measured by benchmarks/fallback_fill.py, 0.126 n^2 at 1436 unknowns
#: (the paper's particle), 0.041 n^2 at 20k (its fine mesh), 0.121 n^2 at 34k (25 grains:
#: 43 times the static factors' entries, 1.77 GB and 116 s against 32 MB and 0.2 s).
PIVOTED_ENTRIES_PER_SQUARED_UNKNOWN = 0.125
#: Peak bytes of a SuperLU factorisation per entry of its factors (value, row index and
#: the work arrays it holds while factorising; 10.0-13.2 measured with the fill above).
BYTES_PER_ENTRY = 13.2


class FactorizationMemoryError(MemoryError):
    """A factorisation refused before it starts: it would need more memory than is left."""


class _Factors(Protocol):
    """What a solve needs of the factors: scipy's ``SuperLU`` or :class:`_PermutedLU`."""

    def solve(self, b: np.ndarray) -> np.ndarray: ...


class SuperLUSolver(SaddlePointSolver):
    """Sparse LU factorisation by SuperLU (scipy), reused across solves.

    The zero pressure block makes SuperLU pivot off the diagonal, which
    destroys the fill-reducing ordering (measured: 11M instead of 2.6M
    factor entries and 15x the time on a 20k-DOF Stokes system). So the
    factorised matrix carries a tiny pressure-mass regularisation
    ``-delta Mp`` that lets every pivot stay on the diagonal (static
    pivoting), and each solve runs iterative refinement against the exact
    matrix until the residual is at round-off. If refinement stalls, the
    solver falls back to an ordinary threshold-pivoted factorisation.

    The ordering (mesh ordering or SuperLU's own) eliminates the pressure at
    a vertex after the velocities there, so the regularisation can be tiny:
    measured relative residuals after one / two triangular solves, BDF2
    Newton matrix with 77k unknowns: 1.9e-6 / 1.1e-9 with ``delta = 1e-8``
    (4 solves to reach 1e-13), 1.9e-9 / 3.8e-14 with ``1e-11`` (2 solves),
    6.2e-9 at 8k unknowns with ``1e-12`` (round-off starts to grow).

    Parameters
    ----------
    delta : float
        Size of the regularisation relative to the velocity block; 0 turns
        static pivoting off.
    refine_rtol : float
        Relative residual at which iterative refinement stops.
    """

    name = "superlu"

    #: Largest relative residual of an unrefined solve that the factors are trusted with.
    INEXACT_RTOL = 1e-6

    def __init__(self, delta: float = 1e-11, refine_rtol: float = 1e-13, max_refine: int = 8):
        super().__init__()
        self.delta = delta
        self.refine_rtol = refine_rtol
        self.max_refine = max_refine
        # the factors and the matrix they refine against
        self._lu: _Factors | None = None
        self._A: sp.csr_matrix | None = None
        self._static = False

    def factorize(self, A: sp.spmatrix, nu: int, **blocks) -> SuperLUSolver:
        """Prepare to solve with ``A`` (velocity unknowns first, ``nu`` of them).

        With an ``ordering`` block and a pattern seen before, scaling,
        regularisation and permutation are gathers through a cached
        :class:`~skfem_granular.fluid.factor_plan.FactorPlan`. ``A`` itself is
        kept (not copied) for the residuals of iterative refinement: do not
        modify it while solving with these factors.

        Parameters
        ----------
        A : sparse matrix
            The saddle-point matrix, velocities first.
        nu : int
            Number of velocity unknowns.
        **blocks
            ``ordering`` (a permutation of the unknowns to factorise in) and ``Mp``
            (the pressure mass matrix, shape of the regularisation); others are ignored.

        Raises
        ------
        ValueError
            If ``ordering`` is not a permutation of ``0 .. A.shape[0] - 1``.
        """
        # the previous factors go first: kept until the new ones exist, both sets would be
        # alive at once (95k-DOF steady Newton solve: peak 1206 -> 766 MB)
        self._lu = self._A = None
        t0 = time.perf_counter()
        self.nu = nu
        A = self._canonical(A)
        perm = blocks.get("ordering")
        if perm is not None:
            perm = np.asarray(perm)
            if perm.shape != (A.shape[0],):
                raise ValueError(f"ordering: length {perm.size}, expected the matrix size "
                                 f"{A.shape[0]}")
            if not _is_permutation(perm):
                raise ValueError(f"ordering: must be a permutation of 0 .. {A.shape[0] - 1} "
                                 "(integers, each once)")
        self._static = self.delta > 0 and A.shape[0] > nu
        self._refined_ok = False  # set by the first refined solve that converges
        plan = (plan_for(A, nu, perm, blocks.get("Mp"))
                if perm is not None and self._static else None)
        if plan is not None:
            s, scaled, vmax = plan.scale(A.data)
            self._scale = np.ones(A.shape[0])
            self._scale[nu:] = s
            CT = plan.permuted_transpose(scaled, self.delta * vmax)
            del scaled
        else:
            CT = self._regularised(A, perm, blocks.get("Mp"))
        # only ``A`` and SuperLU's input are alive while it factorises: the residuals of
        # the scaled system are ``D (A (D y))``, no scaled copy is kept (20 MB at 95k DOFs)
        self._A = A
        if CT is None:
            self._pivoted()
        elif perm is None:
            self._lu = spla.splu(CT, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                 options=dict(SymmetricMode=True))
        else:
            self._lu = _PermutedLU(CT, perm)
        del CT
        self.stats.factorizations += 1
        self.stats.time_factor += time.perf_counter() - t0
        return self

    def _regularised(self, A: sp.csr_matrix, perm, Mp) -> sp.csc_matrix | None:
        """SuperLU's input for ``D A D - reg``: in the order ``perm`` (transposed, see
        :class:`_PermutedLU`) or unpermuted; None without static pivoting."""
        if not self._static:
            self._scale = self._pressure_scale(A, self.nu)  # for the pivoted factorisation
            return None
        n, nu = A.shape[0], self.nu
        if perm is None:
            S = self._scaled(A, nu)
            # typical velocity pivot (not the max: rigid-body rows of a coupled system are
            # huge); D is 1 on the velocities, so D A D has A's velocity diagonal
            R = self._regularisation(n, float(np.median(np.abs(S.diagonal()[:nu]))), Mp)
            return (S - R).tocsc()  # the scaled copy goes as soon as the difference exists
        from .factor_input_numba import permuted_transpose

        self._scale = self._pressure_scale(A, nu)  # A: canonical (factorize made it so)
        R = self._regularisation(n, float(np.median(np.abs(A.diagonal()[:nu]))), Mp)
        perm = np.asarray(perm, dtype=np.int64)
        inv = np.empty_like(perm)
        inv[perm] = np.arange(n)
        # scaling, regularisation, permutation and transposition in one compiled pass
        # (the arithmetic of D A D - R entry by entry, exact zeros dropped, as scipy's)
        indptr, indices, data = permuted_transpose(A.data, A.indices, A.indptr, self._scale,
                                                   R.data, R.indices, R.indptr, perm, inv)
        if indptr[-1] < 2**31 - 1:
            indptr = indptr.astype(np.int32)
        return sp.csc_matrix((data, indices, indptr), shape=(n, n))

    def _regularisation(self, n: int, vmax: float, Mp) -> sp.csr_matrix:
        """``reg``, canonical CSR: ``delta vmax`` times the (scaled, normalised) pressure
        mass matrix, or times the identity on the pressures without one."""
        nu = self.nu
        if Mp is None:
            return sp.csr_matrix((np.full(n - nu, self.delta * vmax),
                                  (np.arange(nu, n), np.arange(nu, n))), shape=(n, n))
        Mp = sp.csr_matrix(Mp) * self._scale[-1] ** 2
        R = sp.block_diag([sp.csr_matrix((nu, nu)),
                           Mp * (self.delta * vmax / abs(Mp).max())], format="csr")
        R.sum_duplicates()
        return R

    def release(self) -> None:
        """Drop the factors and the matrix kept for refinement (the scale stays)."""
        self._lu = self._A = None

    def _scaled_product(self, y: np.ndarray) -> np.ndarray:
        """``D A D y`` for the kept ``A`` and pressure scale ``D``."""
        return self._scale * (self._A @ (self._scale * y))

    def _pivoted(self):
        """Threshold-pivoted factors of ``D A D`` with the scale of this factorisation (a
        solve that falls back here has already scaled its right-hand side by it).

        Raises
        ------
        FactorizationMemoryError
            For a saddle-point matrix (pressure unknowns present), if factors of
            :data:`PIVOTED_ENTRIES_PER_SQUARED_UNKNOWN` ``n^2`` entries would not fit in
            the memory left (:func:`skfem_granular.memory.available`).
        """
        n = self._A.shape[0]
        need = PIVOTED_ENTRIES_PER_SQUARED_UNKNOWN * BYTES_PER_ENTRY * float(n) ** 2
        left = memory.available() if n > self.nu else None
        if left is not None and need > left:
            why = ("iterative refinement stalled and the threshold-pivoted factorisation it "
                   "falls back to" if self._static else
                   "a threshold-pivoted factorisation (no static pivoting: delta = 0)")
            raise FactorizationMemoryError(
                f"SuperLU: on {n} unknowns {why} would need about {need / 1e9:.3g} GB, "
                f"{left / 1e9:.3g} GB left; a singular or inconsistent system, or too "
                "large for threshold pivoting")
        self._static = False
        self._lu = spla.splu(self._with_scale(self._A).tocsc(), permc_spec="MMD_AT_PLUS_A",
                             diag_pivot_thresh=0.01, options=dict(SymmetricMode=True))

    def solve_correction(self, b):
        """One triangular solve with the regularised factors, no refinement.

        Its relative error is about the regularisation (~1e-9 with the default ``delta``),
        far below the contraction of the Newton or chord iteration that calls it. The
        first solve after each factorisation checks the factors by its residual (one
        matrix-vector product); above :attr:`INEXACT_RTOL` it is refined as in
        :meth:`solve` (which falls back to threshold pivoting if refinement stalls).
        """
        if not self._static:
            return self.solve(b)
        self._check_factors()
        t0 = time.perf_counter()
        bs = self._scale * b
        y = self._lu.solve(bs)
        if not self._refined_ok:
            bnorm = np.linalg.norm(bs)
            if np.linalg.norm(bs - self._scaled_product(y)) > self.INEXACT_RTOL * bnorm:
                return self.solve(b)
            self._refined_ok = True
        x = self._scale * y
        self.stats.solves += 1
        self.stats.time_solve += time.perf_counter() - t0
        return x

    def _check_factors(self) -> None:
        if self._lu is None:
            raise RuntimeError("SuperLUSolver: no factorisation held (factorize was not "
                               "called, or release dropped it): factorize before solving")

    def _solve(self, b):
        self._check_factors()
        x = self._lu.solve(b)
        if not self._static:
            return x
        bnorm = np.linalg.norm(b)
        if bnorm == 0.0:
            return x
        prev = np.inf
        for _ in range(self.max_refine):
            r = b - self._scaled_product(x)
            rn = np.linalg.norm(r) / bnorm
            if rn <= self.refine_rtol:
                self._refined_ok = True
                return x
            if not rn < 0.5 * prev:  # stalled: factorise with pivoting instead
                break
            prev = rn
            x = x + self._lu.solve(r)
        if np.linalg.norm(b - self._scaled_product(x)) / bnorm <= self.refine_rtol * 10:
            return x
        self._pivoted()
        return self._lu.solve(b)


def _is_permutation(perm: np.ndarray) -> bool:
    """True for an integer array holding each of ``0 .. perm.size - 1`` once."""
    if perm.dtype.kind not in "iu":
        return False
    if perm.size == 0:
        return True
    if perm.min() < 0 or perm.max() >= perm.size:
        return False
    return bool(np.bincount(perm, minlength=perm.size).max() == 1)


class _PermutedLU:
    """SuperLU factors of ``P A P^T`` for a given ordering, applied to ``A``.

    SuperLU factorises the symmetrically permuted matrix in its natural order
    (it still postorders the elimination tree) with diagonal pivots, so the
    caller's ordering is kept. It factorises the transpose, whose CSC arrays
    are the CSR arrays of ``P A P^T`` (a row gather, no format conversion),
    and solves with ``trans="T"``.
    """

    def __init__(self, CT: sp.csc_matrix, perm: np.ndarray):
        self.perm = perm
        self.lu = spla.splu(CT, permc_spec="NATURAL", diag_pivot_thresh=0.0,
                            options=dict(SymmetricMode=True))

    @property
    def L(self) -> sp.csc_matrix:
        """Lower factor of the permuted matrix."""
        return self.lu.L

    @property
    def U(self) -> sp.csc_matrix:
        """Upper factor of the permuted matrix."""
        return self.lu.U

    def solve(self, b: np.ndarray) -> np.ndarray:
        x = np.empty_like(b, dtype=float)
        x[self.perm] = self.lu.solve(np.ascontiguousarray(b[self.perm], dtype=float), trans="T")
        return x
