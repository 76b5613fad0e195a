"""Linear solvers for the saddle-point systems, behind one small interface.

A solver is built for one matrix (``factorize``) and applied many times
(``solve``), as pyamg's solver objects are. All of them scale the pressure
unknowns first: unscaled, a P2/P1 system in SI units has a condition number
of ~1e12 and a small Krylov residual can hide a badly wrong pressure.

- :class:`SuperLUSolver`: sparse LU (scipy), ordering and options measured
  to fill least on these systems (DESIGN.md, Measured facts).
- :class:`PardisoSolver`: Intel MKL PARDISO through ``pypardiso`` (optional
  extra ``skfem-granular[pardiso]``).
- :class:`KrylovSolver`: FGMRES with a block-triangular preconditioner: pyamg
  smoothed aggregation on the velocity block and a Cahouet-Chabard pressure
  Schur complement approximation ``eta Mp^-1 + a0 rho Lp^-1``.

:func:`make_solver` picks one by size (``"auto"``) or by name.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .factor_plan import plan_for

#: Above this many unknowns ``"auto"`` switches from SuperLU to Krylov.
AUTO_KRYLOV_SIZE = 250_000


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

    def _scaled(self, A: sp.spmatrix, nu: int) -> sp.csr_matrix:
        A = sp.csr_matrix(A)
        if not A.has_canonical_format:
            A = A.copy()
            A.sum_duplicates()
        diag = np.abs(A.diagonal()[:nu])
        rows = np.repeat(np.arange(A.shape[0]), np.diff(A.indptr))
        upper_right = (rows < nu) & (A.indices >= nu)  # the B^T block
        bmax = np.abs(A.data[upper_right]).max() if upper_right.any() else 1.0
        s = (np.median(diag[diag > 0]) / bmax) if np.any(diag > 0) and bmax > 0 else 1.0
        self._scale = np.ones(A.shape[0])
        self._scale[nu:] = s
        # D A D with D = diag(scale), entry by entry as the sparse product computes it
        # ((d_i a_ij) d_j, exact zeros dropped), without two sparse matrix products
        data = (self._scale[rows] * A.data) * self._scale[A.indices]
        keep = data != 0
        if keep.all():
            DAD = sp.csr_matrix((data, A.indices, A.indptr), shape=A.shape)
        else:
            kept = np.concatenate(([0], np.cumsum(keep)))
            DAD = sp.csr_matrix((data[keep], A.indices[keep], kept[A.indptr]), shape=A.shape)
        return DAD

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
        t0 = time.perf_counter()
        x = self._scale * self._solve(self._scale * b)
        self.stats.solves += 1
        self.stats.time_solve += time.perf_counter() - t0
        return x

    def _solve_inexact(self, b: np.ndarray) -> np.ndarray:
        """Solve for a correction inside an outer iteration that evaluates the exact residual.

        A chord or Newton loop corrects the error of each linear solve itself, so solvers
        that refine iteratively may skip it here; the default is :meth:`solve`.
        """
        return self.solve(b)

    def _factorize(self, A, **blocks):
        raise NotImplementedError

    def _solve(self, b):
        raise NotImplementedError


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

    def factorize(self, A: sp.spmatrix, nu: int, **blocks) -> SuperLUSolver:
        """Prepare to solve with ``A`` (velocity unknowns first, ``nu`` of them).

        With an ``ordering`` block and a pattern seen before, scaling,
        regularisation and permutation are gathers through a cached
        :class:`~skfem_granular.fluid.factor_plan.FactorPlan`.
        """
        perm = blocks.get("ordering")
        if (perm is not None and self.delta > 0 and sp.issparse(A) and A.format == "csr"
                and A.shape[0] > nu and np.shape(perm) == (A.shape[0],)):
            t0 = time.perf_counter()
            plan = plan_for(A, nu, perm, blocks.get("Mp"))
            if plan is not None:
                self.nu = nu
                s, scaled, vmax = plan.scale(A.data)
                self._scale = np.ones(A.shape[0])
                self._scale[nu:] = s
                self._A = sp.csr_matrix((scaled, A.indices, A.indptr), shape=A.shape)
                self._static, self._refined_ok = True, False
                self._lu = _PermutedLU(plan.permuted_transpose(scaled, self.delta * vmax), perm)
                self.stats.factorizations += 1
                self.stats.time_factor += time.perf_counter() - t0
                return self
        return super().factorize(A, nu, **blocks)

    def _factorize(self, A, ordering=None, **blocks):
        self._A = A.tocsr()
        if ordering is not None:
            ordering = np.asarray(ordering)
            if ordering.shape != (A.shape[0],):
                raise ValueError(f"ordering: length {ordering.size}, expected the matrix size "
                                 f"{A.shape[0]}")
        self._static = self.delta > 0 and A.shape[0] > self.nu
        self._refined_ok = False  # set by the first refined solve that converges
        if self._static:
            n, nu = A.shape[0], self.nu
            # typical velocity pivot (not the max: rigid-body rows of a coupled system are huge)
            vmax = float(np.median(np.abs(self._A.diagonal()[:nu])))
            Mp = blocks.get("Mp")
            if Mp is None:
                reg = sp.diags(np.r_[np.zeros(nu), np.full(n - nu, self.delta * vmax)])
            else:
                Mp = sp.csr_matrix(Mp) * self._scale[-1] ** 2
                reg = sp.block_diag([sp.csr_matrix((nu, nu)),
                                     Mp * (self.delta * vmax / abs(Mp).max())])
            if ordering is None:
                self._lu = spla.splu((A - reg).tocsc(), permc_spec="MMD_AT_PLUS_A",
                                     diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))
            else:
                self._lu = _PermutedLU.of(A - reg, ordering)
        else:
            self._pivoted(A)

    def _pivoted(self, A):
        self._static = False
        self._lu = spla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.01,
                             options=dict(SymmetricMode=True))

    def _solve_inexact(self, b):
        """One triangular solve with the regularised factors, no refinement.

        Its relative error is about the regularisation (~1e-9 with the default ``delta``),
        far below the contraction of the Newton or chord iteration that calls it. The
        first solve after each factorisation checks the factors by its residual (one
        matrix-vector product); above :attr:`INEXACT_RTOL` it is refined as in
        :meth:`solve` (which falls back to threshold pivoting if refinement stalls).
        """
        if not self._static:
            return self.solve(b)
        t0 = time.perf_counter()
        bs = self._scale * b
        y = self._lu.solve(bs)
        if not self._refined_ok:
            bnorm = np.linalg.norm(bs)
            if np.linalg.norm(bs - self._A @ y) > self.INEXACT_RTOL * bnorm:
                return self.solve(b)
            self._refined_ok = True
        x = self._scale * y
        self.stats.solves += 1
        self.stats.time_solve += time.perf_counter() - t0
        return x

    def _solve(self, b):
        x = self._lu.solve(b)
        if not self._static:
            return x
        bnorm = np.linalg.norm(b)
        if bnorm == 0.0:
            return x
        prev = np.inf
        for _ in range(self.max_refine):
            r = b - self._A @ x
            rn = np.linalg.norm(r) / bnorm
            if rn <= self.refine_rtol:
                self._refined_ok = True
                return x
            if not rn < 0.5 * prev:  # stalled: factorise with pivoting instead
                break
            prev = rn
            x = x + self._lu.solve(r)
        if np.linalg.norm(b - self._A @ x) / bnorm <= self.refine_rtol * 10:
            return x
        self._pivoted(self._A)
        return self._lu.solve(b)


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

    @classmethod
    def of(cls, A: sp.csr_matrix, perm: np.ndarray) -> _PermutedLU:
        """Factors of any ``A`` (CSR) in the order ``perm``."""
        rows = sp.csr_matrix(A)[perm]  # row gather: cheap for CSR
        inv = np.empty_like(perm)
        inv[perm] = np.arange(perm.size)
        CT = sp.csc_matrix((rows.data, inv[rows.indices], rows.indptr), shape=A.shape[::-1])
        CT.sort_indices()
        return cls(CT, perm)

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


class PardisoSolver(SaddlePointSolver):
    """MKL PARDISO through the optional ``pypardiso`` package."""

    name = "pardiso"

    def __init__(self):
        try:
            import pypardiso
        except ImportError as exc:
            raise ValueError("solver = 'pardiso': needs the optional package pypardiso "
                             "(pip install 'skfem-granular[pardiso]')") from exc
        super().__init__()
        self._solver = pypardiso.PyPardisoSolver()

    def _factorize(self, A, **blocks):
        self._A = sp.csr_matrix(A)
        self._solver.factorize(self._A)

    def _solve(self, b):
        return self._solver.solve(self._A, np.ascontiguousarray(b, dtype=np.float64))


class KrylovSolver(SaddlePointSolver):
    """FGMRES with a pyamg block-triangular preconditioner.

    Velocity block: conjugate gradients to ``inner_rtol`` preconditioned by
    smoothed aggregation when it is symmetric (Stokes, BDF2-Stokes), whose
    near-nullspace is the two constant vector fields (the free velocity
    unknowns come in interleaved ``(x, y)`` pairs); GMRES with an
    incomplete LU factorisation when it is not (Newton steps of steady
    Navier-Stokes: smoothed aggregation did not converge on the
    convection-dominated block).

    Pressure Schur complement: Cahouet-Chabard, ``S^-1 ~ eta Mp^-1 + a0 rho
    Lp^-1`` with the pressure mass matrix factorised exactly, when the
    block is symmetric and the caller passes ``eta`` (and ``a0rho``, ``Lp``
    for time steps). Otherwise the least-squares commutator ``S^-1 ~ L^-1
    (B Q^-1 A Q^-1 B^T) L^-1``, ``L = B Q^-1 B^T``, ``Q = diag(A)``, which
    needs no parameters and sees convection and any extra unknowns in the
    velocity block (rigid-body velocities of a coupled system).

    Measured FGMRES iterations (relative residual 1e-10): steady Stokes,
    annulus with 64 segments (10k unknowns) 36 (a single V-cycle with a
    lumped mass matrix needed 208, the commutator 64); steady Navier-Stokes
    at Re 100 on 32 segments 34-67 (Cahouet-Chabard stalled from Re ~30 on);
    a coupled BDF2 step with a rigid particle 7-15 (Cahouet-Chabard without
    the viscosity did not converge in 300).

    Parameters
    ----------
    rtol : float
        Relative residual tolerance of FGMRES (on the scaled system).
    maxiter : int
        Limit on the total number of FGMRES iterations; exceeding it raises
        :class:`ConvergenceError`.
    restart : int
        Krylov vectors kept before a restart (memory: ``2 restart`` vectors
        of the system size).
    inner_rtol : float
        Relative tolerance of the inner velocity solve.
    """

    name = "krylov"

    def __init__(self, rtol: float = 1e-10, maxiter: int = 300, restart: int = 100,
                 inner_rtol: float = 1e-2):
        super().__init__()
        from .._validate import positive

        self.rtol = positive("rtol", rtol)
        self.inner_rtol = positive("inner_rtol", inner_rtol)
        if int(maxiter) < 1 or int(restart) < 1:
            raise ValueError(f"maxiter = {maxiter!r}, restart = {restart!r}: must be >= 1")
        self.maxiter = int(maxiter)
        self.restart = int(restart)

    def _factorize(self, A, Mp=None, Lp=None, eta=None, a0rho=0.0, **blocks):
        import pyamg

        nu = self.nu
        s = self._scale[-1] if self._scale.size > nu else 1.0
        self._A = A.tocsr()
        Auu = self._A[:nu, :nu].tocsr()
        self._Bt = self._A[:nu, nu:]
        amax = abs(Auu).max() if Auu.nnz else 1.0
        self._symmetric = Auu.nnz == 0 or abs(Auu - Auu.T).max() <= 1e-12 * amax
        npr = A.shape[0] - nu
        self._Auu = Auu
        # velocity block
        if self._symmetric:
            B = None
            if nu >= 2 and nu % 2 == 0:  # near-nullspace: x and y translations
                B = np.zeros((nu, 2))
                B[0::2, 0] = 1.0
                B[1::2, 1] = 1.0
            self._ml_u = pyamg.smoothed_aggregation_solver(Auu, B=B, symmetry="symmetric")
        else:
            self._ilu = spla.spilu(Auu.tocsc(), drop_tol=1e-4, fill_factor=10)
            self._ilu_op = spla.LinearOperator((nu, nu), matvec=self._ilu.solve, dtype=float)
        # Schur complement: Cahouet-Chabard needs the viscosity, else least-squares commutator
        self._lsc = not self._symmetric or eta is None
        if not npr:
            return
        if self._lsc:
            Qinv = sp.diags(1.0 / np.maximum(np.abs(Auu.diagonal()), 1e-300))
            B = self._A[nu:, :nu]
            QBt = Qinv @ self._Bt
            self._lsc_L = spla.splu(sp.csc_matrix(B @ QBt))
            self._lsc_F = (B @ Qinv @ Auu @ QBt).tocsr()
            return
        if Mp is None:
            Mp = sp.identity(npr)
        # Schur complement of the scaled system: s^2 * (eta Mp^-1 + a0 rho Lp^-1)^-1 (negated)
        self._mp_lu = spla.splu(sp.csc_matrix(Mp))
        self._eta, self._a0rho, self._s = float(eta), a0rho, s
        self._ml_p = None
        if Lp is not None and a0rho > 0:
            Lreg = (Lp + 1e-8 * abs(Lp).max() * sp.identity(npr)).tocsr()
            self._ml_p = pyamg.smoothed_aggregation_solver(Lreg)

    def _schur(self, rp):
        """Approximate ``S^-1 rp`` for the scaled system (``S`` negative definite)."""
        if self._lsc:
            return -self._lsc_L.solve(self._lsc_F @ self._lsc_L.solve(rp))
        zp = self._eta * self._mp_lu.solve(rp)
        if self._ml_p is not None:
            zp = zp + self._a0rho * self._ml_p.solve(rp, tol=1e-3, maxiter=2, cycle="V")
        return -zp / self._s**2

    def _velocity(self, ru):
        if self._symmetric:
            return self._ml_u.solve(ru, tol=self.inner_rtol, maxiter=20, cycle="V", accel="cg")
        zu, _ = spla.gmres(self._Auu, ru, M=self._ilu_op, rtol=self.inner_rtol, atol=0.0,
                           restart=30, maxiter=2)
        return zu

    def _precondition(self, r):
        nu = self.nu
        ru, rp = r[:nu], r[nu:]
        if rp.size:
            zp = self._schur(rp)
            ru = ru - self._Bt @ zp
        else:
            zp = rp
        return np.concatenate([self._velocity(ru), zp])

    def _solve(self, b):
        from pyamg.krylov import fgmres

        from .errors import ConvergenceError

        n = b.size
        M = spla.LinearOperator((n, n), matvec=self._precondition, dtype=float)
        restart = min(self.restart, self.maxiter, n)
        outer = -(-self.maxiter // restart)
        residuals = []
        x, info = fgmres(self._A, b, M=M, tol=self.rtol, restart=restart, maxiter=outer,
                         residuals=residuals)
        its = len(residuals) - 1
        self.stats.iterations.append(its)
        rel = np.linalg.norm(b - self._A @ x) / max(np.linalg.norm(b), 1e-300)
        if info != 0 or not rel <= self.rtol * 10:
            raise ConvergenceError(f"Krylov solver: FGMRES stopped after {its} "
                                   f"iterations at relative residual {rel:.2e} > rtol "
                                   f"{self.rtol:.0e}; use solver='superlu' or a larger maxiter")
        return x


SOLVERS = {"superlu": SuperLUSolver, "pardiso": PardisoSolver, "krylov": KrylovSolver}


def make_solver(solver: str | SaddlePointSolver = "auto", size: int = 0) -> SaddlePointSolver:
    """Return a new solver object.

    Parameters
    ----------
    solver : {"auto", "superlu", "pardiso", "krylov"} or SaddlePointSolver
        ``"auto"`` uses SuperLU up to :data:`AUTO_KRYLOV_SIZE` unknowns and
        Krylov above. An existing solver object is returned as it is.
    size : int
        Number of unknowns, for ``"auto"``.
    """
    if isinstance(solver, SaddlePointSolver):
        return solver
    if not isinstance(solver, str) or solver not in ("auto", *SOLVERS):
        raise ValueError(f"solver = {solver!r}: must be a SaddlePointSolver or one of 'auto', "
                         f"{', '.join(map(repr, SOLVERS))}")
    if solver == "auto":
        solver = "krylov" if size > AUTO_KRYLOV_SIZE else "superlu"
    return SOLVERS[solver]()
