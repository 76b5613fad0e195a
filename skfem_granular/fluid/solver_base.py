"""Base of the saddle-point solvers: pressure scaling, statistics, the interface.

A solver is built for one matrix (``factorize``) and applied many times
(``solve``). Unscaled, a P2/P1 system in SI units has a condition number of
~1e12 and a small Krylov residual can hide a badly wrong pressure: every
solver scales the pressure unknowns first.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp


@dataclass
class SolverStats:
    """Counters and wall times of one solver object."""

    name: str
    factorizations: int = 0
    solves: int = 0
    iterations: list = field(default_factory=list)
    time_factor: float = 0.0
    time_solve: float = 0.0

    def as_dict(self) -> dict:
        """Plain dictionary (JSON-friendly)."""
        return {"name": self.name, "factorizations": self.factorizations,
                "solves": self.solves, "krylov_iterations": list(self.iterations),
                "time_factor": self.time_factor, "time_solve": self.time_solve}


class SaddlePointSolver:
    """Base class: pressure scaling and bookkeeping.

    Parameters
    ----------
    nu : int
        Number of (free) velocity unknowns; the rest are pressures.
    """

    name = "base"

    def __init__(self):
        self.stats = SolverStats(self.name)
        self._scale = None

    @staticmethod
    def _canonical(A: sp.spmatrix) -> sp.csr_matrix:
        """``A`` in CSR format with sorted, unique entries (a copy only when needed)."""
        A = sp.csr_matrix(A)
        if not A.has_canonical_format:
            A = A.copy()
            A.sum_duplicates()
        return A

    def _scaled(self, A: sp.spmatrix, nu: int) -> sp.csr_matrix:
        """``D A D`` with the pressure scale ``D`` (set as :attr:`_scale`)."""
        A = self._canonical(A)
        self._scale = self._pressure_scale(A, nu)
        return self._with_scale(A)

    @staticmethod
    def _pressure_scale(A: sp.csr_matrix, nu: int) -> np.ndarray:
        """The diagonal of ``D``: 1 on the velocities, ``median |A_uu diagonal| / max |B^T|``
        on the pressures (``A`` canonical CSR)."""
        from .factor_input_numba import upper_right_max

        diag = np.abs(A.diagonal()[:nu])
        bmax = upper_right_max(A.data, A.indices, A.indptr, nu)  # over the B^T block
        bmax = 1.0 if bmax < 0 else bmax  # -1: no such entries
        s = (np.median(diag[diag > 0]) / bmax) if np.any(diag > 0) and bmax > 0 else 1.0
        scale = np.ones(A.shape[0])
        scale[nu:] = s
        return scale

    def _with_scale(self, A: sp.csr_matrix) -> sp.csr_matrix:
        """``D A D`` for ``A`` (canonical CSR) and the kept scale :attr:`_scale`."""
        rows = np.repeat(np.arange(A.shape[0]), np.diff(A.indptr))
        # D A D with D = diag(scale), entry by entry as the sparse product computes it
        # ((d_i a_ij) d_j, exact zeros dropped), without two sparse matrix products
        data = (self._scale[rows] * A.data) * self._scale[A.indices]
        keep = data != 0
        if keep.all():
            return sp.csr_matrix((data, A.indices, A.indptr), shape=A.shape)
        kept = np.concatenate(([0], np.cumsum(keep)))
        return sp.csr_matrix((data[keep], A.indices[keep], kept[A.indptr]), shape=A.shape)

    def factorize(self, A: sp.spmatrix, nu: int, **blocks) -> SaddlePointSolver:
        """Prepare to solve with ``A`` (velocity unknowns first, ``nu`` of them)."""
        t0 = time.perf_counter()
        self.nu = nu
        self._factorize(self._scaled(A, nu), **blocks)
        self.stats.factorizations += 1
        self.stats.time_factor += time.perf_counter() - t0
        return self

    def solve(self, b: np.ndarray) -> np.ndarray:
        """Solve ``A x = b`` with the matrix of the last :meth:`factorize`."""
        if self._scale is None:
            raise RuntimeError(f"{type(self).__name__}: factorize before solving")
        t0 = time.perf_counter()
        x = self._scale * self._solve(self._scale * b)
        self.stats.solves += 1
        self.stats.time_solve += time.perf_counter() - t0
        return x

    def solve_correction(self, b: np.ndarray) -> np.ndarray:
        """Solve for a correction inside an outer iteration that evaluates the exact residual.

        A chord or Newton loop corrects the error of each linear solve itself, so solvers
        that refine iteratively may skip it here; the default is :meth:`solve`.
        """
        return self.solve(b)

    def release(self) -> None:
        """Drop what the factorisation holds when it will not be solved with again (a
        Newton loop refactorises at every iteration): its memory is free for the next
        assembly. After it, :meth:`solve` needs a new :meth:`factorize`. What a solver
        keeps for its next factorisation (PARDISO's analysis) stays; the default keeps
        everything."""

    def _factorize(self, A, **blocks):
        raise NotImplementedError

    def _solve(self, b):
        raise NotImplementedError
