"""Linear solvers for the saddle-point systems, behind one small interface.

A solver is built for one matrix (``factorize``) and applied many times
(``solve``), as pyamg's solver objects are; all of them scale the pressure
unknowns first (``solver_base``).

- :class:`SuperLUSolver` (module ``superlu``): sparse LU (scipy) with static
  pivoting and the mesh's fill-reducing ordering (``ordering``,
  ``factor_plan``).
- :class:`PardisoSolver`: Intel MKL PARDISO through ``pypardiso`` (optional
  extra ``skfem-granular[pardiso]``), bitwise reproducible (MKL's CNR mode).
- :class:`KrylovSolver`: FGMRES with a block-triangular preconditioner: pyamg
  smoothed aggregation on the velocity block and a Cahouet-Chabard pressure
  Schur complement approximation ``eta Mp^-1 + a0 rho Lp^-1``.

:func:`make_solver` picks one by size and by what is installed (``"auto"``) or by
name.
"""

from __future__ import annotations

import copy

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .solver_base import SaddlePointSolver, SolverStats
from .superlu import FactorizationMemoryError, SuperLUSolver

__all__ = ["AUTO_KRYLOV_SIZE", "AUTO_PARDISO_SIZE", "FactorizationMemoryError", "KrylovSolver",
           "PardisoSolver", "SaddlePointSolver", "SolverStats", "SuperLUSolver", "make_solver"]

#: Above this many unknowns ``"auto"`` switches from SuperLU to Krylov (without pypardiso).
#: Measured on dense immersed columns in contact (coupled BDF2/Euler steps, CPU per
#: simulated ms after start-up): 600k unknowns, SuperLU 16.8 s and 2.9 GB peak against
#: 134 s and 5.3 GB on the Krylov path (its incomplete LU of the non-symmetric Jacobian
#: fills in); 1.5M unknowns, SuperLU 116 s, 7.1 GB peak.
AUTO_KRYLOV_SIZE = 2_000_000

#: From this many unknowns on ``"auto"`` takes PARDISO when pypardiso is importable.
AUTO_PARDISO_SIZE = 60_000


class PardisoSolver(SaddlePointSolver):
    """MKL PARDISO through the optional ``pypardiso`` package.

    PARDISO's symbolic analysis (fill-reducing ordering, symbolic factorisation) is
    kept for every later factorisation of the same sparsity pattern, which then runs
    its numerical phase only: a moving mesh keeps its pattern between remeshes, a fixed
    mesh for the whole run.

    Bitwise reproducible by default: PARDISO's conditional numerical reproducibility
    (CNR) mode, ``iparm[33] = PARDISO_CNR_THREADS`` (0-based) with the serial METIS
    ordering (``iparm[1] = 2``; the parallel one rules CNR out), gives the same bits in
    every process whatever the thread count (MKL_NUM_THREADS 1 or 2, threadpoolctl
    limits, a dask worker). PARDISO's own defaults (``reproducible=False``) are not:
    two processes with two threads each gave different last digits on a 77k-unknown
    Newton matrix.

    Parameters
    ----------
    reproducible : bool
        CNR mode (default) or PARDISO's own defaults.
    """

    name = "pardiso"

    def __init__(self, reproducible: bool = True):
        super().__init__()
        self._solver = _pypardiso_solver()
        self._solver.set_statistical_info_off()
        self.reproducible = bool(reproducible)
        if self.reproducible:
            _pardiso_cnr_iparm(self._solver)
        self._pattern = None  # (indptr, indices) of the analysed matrix
        #: factorisations that reused the analysis of the pattern before
        self.analyses_reused = 0

    def _phase(self, phase: int, A, b):
        self._solver.set_phase(phase)
        return self._solver._call_pardiso(A, b)

    def _factorize(self, A, **blocks):
        A = sp.csr_matrix(A)
        A.sort_indices()
        same = (self._pattern is not None and np.array_equal(A.indptr, self._pattern[0])
                and np.array_equal(A.indices, self._pattern[1]))
        # 22: numerical factorisation on the kept analysis; 12: analysis and factorisation
        self._phase(22 if same else 12, A, np.zeros((A.shape[0], 1)))
        self.analyses_reused += same
        self._pattern = (A.indptr.copy(), A.indices.copy())
        self._A = A

    @property
    def factor_memory_mb(self) -> float:
        """Memory MKL keeps for the current factorisation (MB of 10^6 bytes, from what
        PARDISO reports in KiB: the analysis's permanent part plus the numerical factors,
        ``iparm[15] + iparm[16]``, 0-based); 0 before the first factorisation."""
        if self._pattern is None:
            return 0.0
        kib = int(self._solver.iparm[15]) + int(self._solver.iparm[16])
        return kib * 1024 / 1e6

    def _solve(self, b):
        x = self._phase(33, self._A, np.ascontiguousarray(b, dtype=np.float64))
        return np.asarray(x).reshape(b.shape)

    def __del__(self):
        # MKL keeps PARDISO's factors in its own memory until phase -1 releases them;
        # pypardiso never does, so every dropped solver (one per remesh) leaked its
        # factorisation (400-grain collapse, 21 remeshes: peak 12.5 GB)
        solver = self.__dict__.get("_solver")
        if solver is not None and self.__dict__.get("_pattern") is not None:
            try:
                solver.free_memory(everything=True)
            except Exception:  # noqa: BLE001 (interpreter shutdown: MKL may be gone)
                pass


_PYPARDISO_TEMPLATE = None  # the first pypardiso solver, never used to solve


def _pypardiso_solver():
    """A fresh ``pypardiso.PyPardisoSolver``, with MKL looked up once per process.

    pypardiso looks for ``mkl_rt`` in every new solver, here with a recursive glob over
    the environment's library folders (0.55 s a solver measured); later solvers copy the
    first one's library handles and get their own PARDISO handle and parameters.
    """
    global _PYPARDISO_TEMPLATE
    if _PYPARDISO_TEMPLATE is None:
        try:
            import pypardiso
        except ImportError as exc:
            raise ValueError("solver = 'pardiso': needs the optional package pypardiso "
                             "(pip install 'skfem-granular[pardiso]')") from exc
        _PYPARDISO_TEMPLATE = pypardiso.PyPardisoSolver()
    solver = copy.copy(_PYPARDISO_TEMPLATE)
    solver.pt = np.zeros_like(_PYPARDISO_TEMPLATE.pt)
    solver.iparm = np.zeros_like(_PYPARDISO_TEMPLATE.iparm)
    solver.perm = np.zeros_like(_PYPARDISO_TEMPLATE.perm)
    solver.factorized_A = sp.csr_matrix((0, 0))
    return solver


#: PARDISO's ``iparm[33]`` in CNR mode: the thread count its reproducible schedule is
#: laid out for (any number of threads actually running gives the same bits).
PARDISO_CNR_THREADS = 2


def _pardiso_cnr_iparm(solver) -> None:
    """Fill a ``pypardiso.PyPardisoSolver``'s ``iparm`` for bitwise reproducible runs.

    ``pardisoinit`` writes MKL's defaults for a real nonsymmetric matrix (``mtype`` 11)
    with ``iparm[0] = 1`` (the values are used as given); then the serial METIS ordering
    and CNR mode are set.
    """
    import ctypes

    init = solver.libmkl.pardisoinit
    init.restype = None
    handle = solver.pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64))
    init(handle, ctypes.byref(ctypes.c_int32(solver.mtype)),
         solver.iparm.ctypes.data_as(ctypes.POINTER(ctypes.c_int32)))
    solver.pt[:] = 0
    solver.iparm[1] = 2  # serial nested dissection (METIS): the parallel one rules out CNR
    solver.iparm[33] = PARDISO_CNR_THREADS


#: Relative tolerance of a Krylov correction inside an outer iteration (see KrylovSolver).
#: Measured on a dense column of 100 grains in water (153,791 unknowns, 6 coupled steps,
#: CPU): 141 s at 1e-10 (17-26 FGMRES iterations a correction), 78 s at 1e-6, 49 s at
#: 1e-4 (2-10 iterations; 36 corrector iterations against 33), the grains' velocities
#: the same to 1.4e-9 m/s (9e-8 of the largest).
CORRECTION_RTOL = 1e-4


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
    correction_rtol : float
        Relative tolerance of :meth:`solve_correction`: a chord or Newton loop that
        evaluates the exact residual needs its corrections only to a contraction well
        below its own (0.01-0.3 per iteration), not to ``rtol``.
    """

    name = "krylov"

    def __init__(self, rtol: float = 1e-10, maxiter: int = 300, restart: int = 100,
                 inner_rtol: float = 1e-2, correction_rtol: float = CORRECTION_RTOL):
        super().__init__()
        from .._validate import positive

        self.rtol = positive("rtol", rtol)
        self.correction_rtol = positive("correction_rtol", correction_rtol)
        self._rtol_now = self.rtol
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
        rtol = self._rtol_now
        x, info = fgmres(self._A, b, M=M, tol=rtol, restart=restart, maxiter=outer,
                         residuals=residuals)
        its = len(residuals) - 1
        self.stats.iterations.append(its)
        rel = np.linalg.norm(b - self._A @ x) / max(np.linalg.norm(b), 1e-300)
        if info != 0 or not rel <= rtol * 10:
            raise ConvergenceError(f"Krylov solver: FGMRES stopped after {its} "
                                   f"iterations at relative residual {rel:.2e} > rtol "
                                   f"{rtol:.0e}; use solver='superlu' or a larger maxiter")
        return x

    def solve_correction(self, b: np.ndarray) -> np.ndarray:
        """:meth:`solve` to ``correction_rtol`` (the outer loop corrects the rest)."""
        self._rtol_now = self.correction_rtol
        try:
            return self.solve(b)
        finally:
            self._rtol_now = self.rtol


SOLVERS = {"superlu": SuperLUSolver, "pardiso": PardisoSolver, "krylov": KrylovSolver}


def make_solver(solver: str | SaddlePointSolver = "auto", size: int = 0, *,
                once: bool = False) -> SaddlePointSolver:
    """Return a new solver object.

    Parameters
    ----------
    solver : {"auto", "superlu", "pardiso", "krylov"} or SaddlePointSolver
        ``"auto"``: PARDISO (:class:`PardisoSolver`, bitwise reproducible) from
        :data:`AUTO_PARDISO_SIZE` unknowns on when ``pypardiso`` is importable; else
        SuperLU up to :data:`AUTO_KRYLOV_SIZE` unknowns and Krylov above. SuperLU is the
        default that always installs. The rule, measured on reduced BDF2 Newton
        matrices (2 cores, loaded machine, SuperLU / PARDISO analysis kept / PARDISO
        first factorisation with its analysis): 72 / 52 / 145 ms at 8k unknowns, 272 /
        222 / 516 ms at 20k, 1134 / 607 / 2174 ms at 77k, 9.8 / 1.2 / 5.3 s at 353k
        (earlier run). A pattern factorised once favours SuperLU up to a few 100k
        unknowns, one factorised again and again (Newton, a fixed or moving mesh
        between remeshes) PARDISO from a few 10k: at 77k one analysis and one
        refactorisation cost what two SuperLU factorisations do. An existing solver
        object is returned as it is.
    size : int
        Number of unknowns, for ``"auto"``.
    once : bool
        The matrix will be factorised once (a Stokes solve): ``"auto"`` then keeps to
        SuperLU / Krylov (measured on the DFG 2D-1 mesh of 95k unknowns: one Stokes solve
        2.0 s with SuperLU, 3.0 s with PARDISO and its analysis).
    """
    if isinstance(solver, SaddlePointSolver):
        return solver
    if not isinstance(solver, str) or solver not in ("auto", *SOLVERS):
        raise ValueError(f"solver = {solver!r}: must be a SaddlePointSolver or one of 'auto', "
                         f"{', '.join(map(repr, SOLVERS))}")
    if solver == "auto":
        if size >= AUTO_PARDISO_SIZE and not once and pardiso_available():
            return PardisoSolver()
        solver = "krylov" if size > AUTO_KRYLOV_SIZE else "superlu"
    return SOLVERS[solver]()


def pardiso_available() -> bool:
    """Whether ``pypardiso`` imports and finds MKL (imported on the first call only)."""
    global _PARDISO_AVAILABLE
    if _PARDISO_AVAILABLE is None:
        try:
            PardisoSolver()
        except (ValueError, ImportError, OSError):
            _PARDISO_AVAILABLE = False
        else:
            _PARDISO_AVAILABLE = True
    return _PARDISO_AVAILABLE


_PARDISO_AVAILABLE: bool | None = None
