"""Steady Stokes and Navier-Stokes solves."""

from __future__ import annotations

import time

import numpy as np

from .boundary import DirichletData
from .continuation import viscosity_continuation
from .errors import ConvergenceError
from .flow import Flow, SolveReport
from .linsolve import make_solver
from .newton import newton_iterate
from .operator import NavierStokesOperator
from .properties import Fluid
from .space import TaylorHood

#: Newton is taken to diverge when the residual exceeds the smallest one seen by this
#: factor (from the third iteration on).
DIVERGED = 1e4

#: Newton iterations allowed to one stage of a continuation.
STAGE_MAXITER = 12


def as_space(mesh_or_space) -> TaylorHood:
    """Return a :class:`TaylorHood` for a mesh (or the space itself)."""
    return mesh_or_space if isinstance(mesh_or_space, TaylorHood) else TaylorHood(mesh_or_space)


def _newton_or_continuation(space, fluid, velocity, initial, options: dict,
                            t_start: float) -> Flow:
    """Newton from ``initial``; if it fails, the path through larger viscosities
    (:func:`~.continuation.viscosity_continuation`), recorded in ``flow.report``."""
    try:
        return solve_steady(space, fluid, velocity, True, initial=initial, continuation="off",
                            **options)
    except ConvergenceError:
        pass

    def stage(fl, start):  # from a close guess Newton needs few iterations, or fails
        return solve_steady(space, fl, velocity, True, initial=start, continuation="off",
                            **dict(options, maxiter=min(options["maxiter"], STAGE_MAXITER)))

    flow, stages = viscosity_continuation(stage, fluid)
    flow.report.continuation = stages
    flow.report.wall_time["total"] = time.perf_counter() - t_start
    return flow


def _initial_state(op, initial) -> np.ndarray:
    """The first iterate: ``initial`` (a Flow or a vector) or zeros, with the boundary data."""
    x = np.zeros(op.space.N)
    if initial is not None:
        x[:] = initial.x if isinstance(initial, Flow) else np.asarray(initial, dtype=float)
    op.apply_dirichlet(x)
    return x


def _flow(op, x: np.ndarray, report: SolveReport, solver_stats: dict, times: dict) -> Flow:
    """The solution as a :class:`Flow` (pressure normalised, the report completed)."""
    op.normalize_pressure(x)
    report.solver = solver_stats
    report.wall_time = times
    nu = op.space.nu

    def residual_u(xx, op=op):
        return op.residual(xx)[:nu]

    return Flow(op, x, residual_u, report=report)


def solve_steady(mesh, fluid: Fluid, velocity: dict, convection: bool = False, *,
                 body_force=None, viscous: str = "auto", solver="auto", tol: float = 1e-10,
                 maxiter: int = 25, initial: Flow | np.ndarray | None = None,
                 continuation: str = "auto", terms=None) -> Flow:
    """Solve the steady Stokes or Navier-Stokes equations.

    Parameters
    ----------
    mesh : skfem.MeshTri or TaylorHood
        Mesh with named boundaries (or a prebuilt discretisation to reuse).
    fluid : Fluid
        Density and viscosity.
    velocity : dict
        ``{boundary name: (u, v) | f(x, y) | RigidMotion}``; boundaries left
        out are "do-nothing" outflow boundaries.
    convection : bool
        ``False``: Stokes (one linear solve). ``True``: Navier-Stokes by
        Newton's method started from the Stokes solution (or ``initial``).
    body_force : None, (2,) or callable, optional
        Force density in N/m^3.
    viscous : {"auto", "symmetric", "laplace"}
        Viscous form; see :class:`NavierStokesOperator`.
    solver : str or SaddlePointSolver
        Linear solver; see :func:`make_solver`.
    tol : float
        Newton stops when the residual of the free DOFs has fallen by
        ``tol`` relative to the Stokes right-hand side, or the update is
        below ``tol`` relative to the solution.
    maxiter : int
        Newton iteration limit.
    initial : Flow or ndarray, optional
        Initial guess for Newton.
    continuation : {"auto", "off"}
        ``"auto"``: when Newton fails (no convergence in ``maxiter`` iterations, or a
        residual :data:`DIVERGED` times above the best one seen), reach the solution
        through larger viscosities (:func:`~.continuation.viscosity_continuation`);
        the path is in ``flow.report.continuation``. ``"off"``: raise instead.
    terms : UserTerms, optional
        scikit-fem forms added to the momentum and continuity equations
        (:class:`~skfem_granular.fluid.user_terms.UserTerms`; ``w["t"]`` is 0). With
        them the solve is Newton's iteration even without convection (a form's
        coefficients may read the velocity ``w["u"]``).

    Returns
    -------
    Flow
        With ``flow.report``: iterations, relative residual history, solver
        statistics and wall times.

    Raises
    ------
    ConvergenceError
        When Newton does not converge within ``maxiter`` iterations (and, with
        ``continuation="auto"``, neither does the continuation).
    """
    if continuation not in ("auto", "off"):
        raise ValueError(f"continuation = {continuation!r}: must be 'auto' or 'off'")
    t_start = time.perf_counter()
    space = as_space(mesh)
    if convection and continuation == "auto":
        options = dict(body_force=body_force, viscous=viscous, solver=solver, tol=tol,
                       maxiter=maxiter, terms=terms)
        return _newton_or_continuation(space, fluid, velocity, initial, options, t_start)
    op = NavierStokesOperator(space, fluid, DirichletData(space, velocity), convection=convection,
                              viscous=viscous, body_force=body_force, terms=terms)
    times = {"setup": time.perf_counter() - t_start, "assembly": 0.0, "solve": 0.0}
    lin = make_solver(solver, op.free.size, once=op.linear)  # Stokes: one factorisation
    free = op.free

    def linear_solve(Jr, r, newton=False):
        t0 = time.perf_counter()
        lin.factorize(Jr, op.nu_free, **op.solver_blocks())
        # a Newton correction needs no refinement: the loop evaluates the exact residual
        dx = lin.solve_correction(-r[free]) if newton else lin.solve(-r[free])
        # never solved with again: the next residual and Jacobian (and the first time, the
        # convection kernel and the Newton pattern) are built without these factors
        # (95k-DOF steady solve: the peak, after the Stokes step, 625 -> 600 MB of RSS)
        lin.release()
        times["solve"] += time.perf_counter() - t0
        return dx

    x = _initial_state(op, initial)
    report = SolveReport()
    # reference size: the residual of the zero-interior state with boundary data
    r = op.residual(x)
    ref = max(float(np.linalg.norm(r[free])), 1e-300)
    if op.linear:
        t0 = time.perf_counter()
        J = op.reduced_jacobian(x)
        times["assembly"] += time.perf_counter() - t0
        x[free] += linear_solve(J, r)
        r = op.residual(x)
        report.iterations = 1
        report.residuals.append(float(np.linalg.norm(r[free]) / ref))
    else:
        known = {"r": r, "failed": False}

        def residual(x):  # the residual stop() evaluated after the last update
            return known["r"]

        def correction(x, r, it):
            t0 = time.perf_counter()
            # a Stokes matrix for the first step from a zero interior, Newton after
            J = (op.reduced_jacobian(x) if (it > 1 or initial is not None)
                 else op.reduced(op.linear_matrix(op.velocity_block(), x)))
            times["assembly"] += time.perf_counter() - t0
            return linear_solve(J, r, newton=True)

        def stop(it, dx, x):
            t0 = time.perf_counter()
            r = known["r"] = op.residual(x)
            times["assembly"] += time.perf_counter() - t0
            rel = float(np.linalg.norm(r[free]) / ref)
            report.residuals.append(rel)
            step = np.linalg.norm(dx) / max(np.linalg.norm(x[free]), 1e-300)
            if not np.isfinite(rel) or (it >= 3 and rel > DIVERGED * min(report.residuals)):
                known["failed"] = True  # diverging: no use iterating to maxiter
                return True
            return rel <= tol or step <= tol

        it = newton_iterate(x, residual, correction, stop, max_iterations=maxiter, index=free)
        report.iterations = maxiter if it is None else it
        if it is None or known["failed"]:
            raise ConvergenceError(
                f"solve_steady: Newton did not converge in {report.iterations} iterations "
                f"(relative residual {report.residuals[-1]:.2e} > tol {tol:.0e}); the Reynolds "
                f"number may be too high for this mesh: try continuation='auto', initial=a "
                f"flow at lower speed, or a larger maxiter")
    times["total"] = time.perf_counter() - t_start
    return _flow(op, x, report, lin.stats.as_dict(), times)
