"""Unsteady Stokes / Navier-Stokes by variable-step BDF2 (the paper's Eq. 1).

:class:`BDF2Integrator` advances ``x = [u, p]`` one step at a time:

1. an explicit second-order predictor (AB2 on the BDF2 derivatives, see
   :mod:`skfem_granular.timestep`) gives the initial guess;
2. the corrector ``[a0 rho M + eta K + rho N(u)  B^T; B  0] [u; p] =
   [-rho M (a1 u_n + a2 u_{n-1}) + f; 0]`` is solved by a fixed-operator
   ("chord") Newton iteration with the factorised BDF2-Stokes operator,
   which is reused while ``dt`` and the step ratio do not change; when the
   chord iteration stalls (convection-dominated steps) the Newton Jacobian at
   the iterate is factorised and the iteration goes on with it, as later steps
   with the same ``a0`` do (:class:`~skfem_granular.fluid.newton.ChordStall`, the
   rule of the coupled corrector too);
3. Milne's device gives the local error from the predictor-corrector
   difference, for adaptive steps.

Without convection (unsteady Stokes) each step is one back-substitution.
The first step is backward Euler. :func:`evolve` wraps it as a generator
yielding ``(t, flow)`` as scikit-fem's ex19 does.
"""

from __future__ import annotations

import math
import time
from typing import cast

import numpy as np

from .. import timestep as ts
from .._validate import positive
from .boundary import DirichletData
from .errors import ConvergenceError
from .factor_cache import FactorCache
from .flow import Flow, SolveReport, StepInfo
from .linsolve import make_solver
from .newton import ChordStall, newton_iterate
from .operator import NavierStokesOperator
from .steady import as_space


class BDF2Integrator:
    """Variable-step BDF2 integrator of the Stokes/Navier-Stokes equations on a fixed mesh.

    Parameters
    ----------
    mesh : skfem.MeshTri or TaylorHood
        Mesh with named boundaries.
    fluid : Fluid
        Density and viscosity.
    velocity : dict
        Boundary data ``{name: (u, v) | f(x, y) | f(x, y, t) | RigidMotion}``.
    convection : bool
        Navier-Stokes (``True``) or unsteady Stokes (``False``).
    u0 : ndarray, Flow or callable, optional
        Initial velocity (DOF vector, a flow on the same mesh, or ``f(x, y)``).
        Default: fluid at rest.
    t0 : float
        Initial time.
    body_force, viscous, solver
        As in :func:`solve_steady`.
    newton_tol : float
        Corrector iterations stop when the velocity update is below
        ``newton_tol`` relative to the velocity scale.
    max_iterations : int
        Corrector iteration limit per step; exceeding it rejects the step.
    velocity_scale : float, optional
        Velocity used to scale errors; default: the largest boundary speed
        (at least 1e-12).
    scheme : {"bdf2", "euler"}
        Variable-step BDF2 (backward Euler on the first step only) or
        backward Euler throughout (first order, for comparison).
    mesh_motion : callable, optional
        ``mesh_motion(t) -> (2, nv)`` vertex positions of a moving mesh (same
        connectivity). The equations are then solved in ALE form: nodal values
        move with the mesh, the convection term is ``((u - w) . grad) u`` with the
        mesh velocity ``w`` the BDF2 derivative of the vertex positions, and every
        block is evaluated on the mesh at the end of the step (a uniform flow stays
        uniform to round-off on any motion). The chord iteration keeps the
        factorisation of an earlier mesh.
    refactor_iterations : int
        On a moving mesh: refactorise after a step that needed more chord
        iterations than this.
    terms : UserTerms, optional
        scikit-fem forms added to the momentum and continuity equations
        (:class:`~skfem_granular.fluid.user_terms.UserTerms`), assembled at the end of
        each step (``w["t"] = t + dt``, on the mesh there) at every corrector iterate.
        The chord operator holds their matrices where it was factorised; with them the
        corrector iterates to ``newton_tol`` even for Stokes.
    """

    def __init__(self, mesh, fluid, velocity: dict, *, convection: bool = True, u0=None,
                 t0: float = 0.0, body_force=None, viscous: str = "auto", solver="auto",
                 newton_tol: float = 1e-8, max_iterations: int = 12,
                 velocity_scale: float | None = None, scheme: str = "bdf2",
                 mesh_motion=None, refactor_iterations: int = 6, terms=None):
        if scheme not in ("bdf2", "euler"):
            raise ValueError(f"scheme = {scheme!r}: must be 'bdf2' or 'euler'")
        self.scheme = scheme
        self.space = as_space(mesh)
        self.op = NavierStokesOperator(self.space, fluid, DirichletData(self.space, velocity),
                                       convection=convection, viscous=viscous,
                                       body_force=body_force, terms=terms)
        self.fluid = fluid
        self.newton_tol = positive("newton_tol", newton_tol)
        self.max_iterations = int(max_iterations)
        self.solver = make_solver(solver, self.op.free.size)
        self.t = float(t0)
        nu = self.space.nu
        self.x = np.zeros(self.space.N)
        if u0 is not None:
            self.x[:nu] = self._initial_velocity(u0)
        self.op.apply_dirichlet(self.x, self.t)
        self.u_prev: np.ndarray | None = None   # u_{n-1}
        self.du = np.zeros(nu)                  # u'_n
        self.du_prev: np.ndarray | None = None  # u'_{n-1}
        self.dt_prev: float | None = None
        if velocity_scale is None:
            vals = self.op.dirichlet.values(self.t)
            velocity_scale = float(np.abs(vals).max()) if vals.size else 0.0
        self.velocity_scale = max(float(velocity_scale), 1e-12)
        self.timings = {"assembly": 0.0, "factorization": 0.0, "solve": 0.0}
        # the chord operator is factorised on the mesh of the last committed step
        self.factors = FactorCache(self.solver, lambda a0: self.op.reduced_bdf2_system(a0),
                                   self.timings)
        if mesh_motion is not None and not callable(mesh_motion):
            raise ValueError("mesh_motion: must be a callable t -> vertex positions (2, nv)")
        self.mesh_motion = mesh_motion
        self.refactor_iterations = int(refactor_iterations)
        # vertex positions at t_n, t_{n-1} (moving meshes)
        self.p_n: np.ndarray | None = None
        self.p_prev: np.ndarray | None = None
        if mesh_motion is not None:
            self.p_n = self._positions(self.t)
            if not np.array_equal(self.p_n, self.space.mesh.p):
                self.space = self.space.moved(self.p_n)
                self.op = self.op.moved(self.space)
                self.op.apply_dirichlet(self.x, self.t)

    def _initial_velocity(self, u0) -> np.ndarray:
        sp_ = self.space
        if isinstance(u0, Flow):
            return u0.u.copy()
        if callable(u0):
            loc = sp_.velocity_doflocs
            ux, uy = u0(loc[0], loc[1])
            val = np.where(sp_.component == 0, ux, uy).astype(float)
        else:
            val = np.asarray(u0, dtype=float)
        if val.shape != (sp_.nu,) or not np.all(np.isfinite(val)):
            raise ValueError(f"u0: must be {sp_.nu} finite velocity DOFs, a Flow or f(x, y)")
        return val

    def _positions(self, t: float) -> np.ndarray:
        p = np.asarray(self.mesh_motion(t), dtype=float)
        shape = self.space.reference.mesh.p.shape
        if p.shape != shape or not np.all(np.isfinite(p)):
            raise ValueError(f"mesh_motion({t:g}): must return finite vertex positions of "
                             f"shape {shape}, got {p.shape}")
        return p

    def _moved_operator(self, bdf2: ts.BDF2):
        """Operator on the mesh at ``t + dt`` and the mesh velocity there (ALE), or the
        fixed mesh's operator and ``None``.

        The mesh velocity is the BDF2 derivative of the vertex positions, the same
        formula as the fluid's time derivative, linear on each triangle.
        """
        if self.mesh_motion is None:
            return self.op, None
        p_new = self._positions(self.t + bdf2.dt)
        op = self.op.moved(self.space.reference.moved(p_new))
        assert self.p_n is not None  # set from the start on a moving mesh
        # a second step on: t_{n-1} was committed
        assert bdf2.euler or self.p_prev is not None
        return op, op.space.vertex_field(bdf2.derivative(p_new, self.p_n, self.p_prev))

    # linear algebra ---------------------------------------------------------------
    def _refresh(self, x: np.ndarray, a0: float, op, w_mesh) -> None:
        """Factorise the Newton Jacobian at ``x`` (on ``op``'s mesh, with its mesh velocity
        ``w_mesh``) and hold it as the chord operator for ``a0``: a stalled chord iteration
        goes on with it, and so do later steps with the same ``a0``."""
        t0 = time.perf_counter()
        if w_mesh is None:
            J = op.reduced_jacobian(x, c_mass=a0)
        else:
            J = op.reduced(op.jacobian(x, a0, w_mesh=w_mesh))
        system = (op.velocity_block(a0), J, op.nu_free, op.solver_blocks(a0))
        self.timings["assembly"] += time.perf_counter() - t0
        self.factors.factorize_system(a0, system)

    def _bdf2(self, dt) -> ts.BDF2:
        return ts.BDF2(dt, None if self.scheme == "euler" else self.dt_prev)

    # one step -----------------------------------------------------------------------
    def try_step(self, dt: float):
        """Compute the corrector for a step of size ``dt`` without committing it.

        Returns
        -------
        x_new : ndarray
        iterations : int
        err : float or None
            Scaled local error estimate (``None`` on the first step).
        refreshes : int
            Newton Jacobians factorised because the chord iteration stalled
            (:class:`~skfem_granular.fluid.newton.ChordStall`).

        Raises
        ------
        ConvergenceError
            When the corrector does not converge.
        """
        nu = self.space.nu
        u_n = self.x[:nu]
        a0, op, w_mesh, rhs_u, A_uu, u_pred, x = self._prepare(dt)
        free = op.free
        # Navier-Stokes: the chord loop re-evaluates the exact residual, so the correction
        # needs no refinement (same iterates to ~1e-13, 2x fewer triangular solves); Stokes
        # steps stop after one exact solve
        solve = self.solver.solve_correction if not op.linear else self.solver.solve
        it_state = {"scale": max(float(np.abs(u_n).max()), self.velocity_scale),
                    "dnorm": math.nan}
        stall = ChordStall(self.max_iterations, self.factors)

        def residual(x):
            t0 = time.perf_counter()
            r = op.residual(x, rhs_u=rhs_u, A_uu=A_uu, w_mesh=w_mesh)
            self.timings["assembly"] += time.perf_counter() - t0
            return r

        def correction(x, r, it):
            if stall.refresh_due(it):
                self._refresh(x, a0, op, w_mesh)  # booked as assembly and factorisation
            t1 = time.perf_counter()
            dx = -solve(r[free])
            self.timings["solve"] += time.perf_counter() - t1
            return dx

        def stop(it, dx, x):
            if op.linear and w_mesh is None:
                return True
            dnorm = float(np.abs(dx[: op.nu_free]).max())
            it_state["dnorm"] = dnorm
            if not math.isfinite(dnorm):
                raise ConvergenceError(f"BDF2 step dt={dt:.3e}: corrector produced NaN")
            # a flow starting from rest has no velocity scale yet: use the iterate's
            scale = it_state["scale"] = max(it_state["scale"], float(np.abs(x[:nu]).max()))
            done = dnorm <= self.newton_tol * scale
            stall.observe(it, dnorm, done, self.newton_tol * scale)
            return done

        it = newton_iterate(x, residual, correction, stop, max_iterations=self.max_iterations,
                            index=free)
        if it is None:
            raise ConvergenceError(
                f"BDF2 step at t={self.t:.6g}, dt={dt:.3e}: corrector did not converge in "
                f"{self.max_iterations} iterations (update {it_state['dnorm']:.2e} > "
                f"{self.newton_tol:.0e} x velocity scale {it_state['scale']:.2e})")
        self._last_rhs = rhs_u
        self._trial = (dt, op, w_mesh, it)
        return x, it, self._error_estimate(dt, x[:nu], u_pred), stall.refreshes

    def _prepare(self, dt: float) -> tuple:
        """What a step of ``dt`` starts from: ``(a0, op, w_mesh, rhs_u, A_uu, u_pred, x)``:
        the BDF2 coefficient, the operator on the (moved) mesh and its mesh velocity, the
        history's right-hand side, the velocity block, the predicted velocity and the
        first iterate (Dirichlet values set)."""
        nu = self.space.nu
        bdf2 = self._bdf2(dt)
        a0 = bdf2.a0
        u_n = self.x[:nu]
        hist = bdf2.history(u_n, self.u_prev)
        t0 = time.perf_counter()
        op, w_mesh = self._moved_operator(bdf2)
        op.time = self.t + dt  # where the user terms are assembled
        rhs_u = -self.fluid.density * (op.space.M @ hist)
        t_op = time.perf_counter()
        A_uu = self.factors.operator(a0)
        t0 += time.perf_counter() - t_op  # the cache books its assembly and factorisation
        if w_mesh is not None:  # the residual on the moved mesh; the factors are the chord's
            A_uu = op.velocity_block(a0)
        u_pred = ts.predict(u_n, self.du, self.du_prev, dt, self.dt_prev)
        x = self.x.copy()
        x[:nu] = u_pred
        op.apply_dirichlet(x, self.t + dt)
        self.timings["assembly"] += time.perf_counter() - t0
        return a0, op, w_mesh, rhs_u, A_uu, u_pred, x

    def _error_estimate(self, dt: float, u_new: np.ndarray, u_pred: np.ndarray) -> float | None:
        """Milne's scaled local error estimate of the step (None on a first step or with
        backward Euler)."""
        if self.dt_prev is None or self.scheme != "bdf2":
            return None
        est = ts.milne_factor(dt, self.dt_prev) * (u_new - u_pred)
        return float(np.abs(est).max()) / max(float(np.abs(u_new).max()), self.velocity_scale)

    def commit(self, x_new: np.ndarray, dt: float) -> None:
        """Make ``x_new`` the state at ``t + dt`` and shift the histories."""
        nu = self.space.nu
        u_n = self.x[:nu]
        du_new = self._bdf2(dt).derivative(x_new[:nu], u_n, self.u_prev)
        self.u_prev = u_n.copy()
        self.du_prev, self.du = self.du, du_new
        self.dt_prev = dt
        self.x = x_new
        self.t += dt
        if self.mesh_motion is not None:
            step, op, _, its = self._trial
            if step != dt:
                raise ValueError(f"commit(dt={dt!r}): the last try_step was for dt={step!r}")
            self.op, self.space = op, op.space
            self.p_prev, self.p_n = self.p_n, op.space.mesh.p
            if its > self.refactor_iterations:  # the chord operator has gone stale
                self.factors.clear()

    def flow(self) -> Flow:
        """The current state as a :class:`Flow` (forces include the fluid inertia)."""
        op = self.op
        x = op.normalize_pressure(self.x.copy())
        A_uu, rhs = self.factors.A_uu, self._last_rhs

        def residual_u(xx):
            return op.residual(xx, rhs_u=rhs, A_uu=A_uu)[: self.space.nu]

        rep = SolveReport(solver=self.solver.stats.as_dict(), wall_time=dict(self.timings))
        return Flow(op, x, residual_u, t=self.t, report=rep)


def evolve(mesh, fluid, velocity: dict, *, dt: float, t_end: float, adaptive: bool = False,
           tol: float = 1e-3, max_ratio: float = 2.0, dt_min: float | None = None,
           dt_max: float = math.inf, max_rejections: int = 10, **options):
    """Integrate in time; a generator yielding ``(t, flow)`` after every accepted step.

    Parameters
    ----------
    mesh, fluid, velocity
        As in :class:`BDF2Integrator`.
    dt : float
        (Initial) step size, > 0.
    t_end : float
        End time, > the initial time.
    adaptive : bool
        Choose steps from the local error estimate (accept/reject).
    tol : float
        Local error tolerance relative to the velocity scale (adaptive).
    max_ratio : float
        Growth cap of consecutive steps, < 1 + sqrt(2).
    dt_min, dt_max : float
        Step bounds (``dt_min`` default ``1e-6 dt``).
    max_rejections : int
        Rejected attempts allowed in a row before giving up, and halvings
        of one attempt after a corrector failure (:func:`~skfem_granular.timestep.accept_step`).
    **options
        Passed to :class:`BDF2Integrator` (``convection``, ``u0``, ``t0``,
        ``body_force``, ``solver``, ``terms``, ...).

    Yields
    ------
    t : float
    flow : Flow
        ``flow.report`` carries the step's :class:`~.flow.StepInfo` as ``flow.step``.
    """
    dt = positive("dt", dt)
    integ = BDF2Integrator(mesh, fluid, velocity, **options)
    if not (math.isfinite(t_end) and t_end > integ.t):
        raise ValueError(f"t_end = {t_end!r}: must be finite and > the initial time {integ.t}")
    ctrl = ts.StepController(tol=tol, max_ratio=max_ratio, dt_max=dt_max,
                             dt_min=dt * 1e-6 if dt_min is None else dt_min)
    while not ts.reached(integ.t, t_end, dt):
        nominal = dt
        # land on t_end exactly; keep dt (and the factorisation) when only rounding differs
        step = ts.step_toward(integ.t, dt, t_end, dt)
        if integ.dt_prev is not None:
            step = min(step, max_ratio * integ.dt_prev)
        t0 = time.perf_counter()
        try:
            acc = ts.accept_step(integ.try_step, step, failure=ConvergenceError,
                                 max_halvings=max_rejections, dt_min=ctrl.dt_min,
                                 controller=ctrl if adaptive else None,
                                 estimate=lambda res, step: res[2],
                                 max_rejections=max_rejections)
        except ts.StepFailedError as exc:
            if exc.reason == "halvings":
                assert exc.__cause__ is not None  # accept_step raises it from the failure
                raise exc.__cause__ from None
            raise ConvergenceError(
                f"evolve: {exc.rejections} rejected steps in a row at t={integ.t:.6g} "
                f"(dt={exc.step:.3e}, error {exc.error:.2e} > tol {tol:.0e})") from None
        # what try_step returns (AcceptedStep.result is typed object)
        x, its, err, refreshes = cast("tuple[np.ndarray, int, float | None, int]", acc.result)
        step, rejected = acc.step, acc.halvings + acc.rejections
        if adaptive and err is not None:
            assert acc.proposal is not None  # the controller proposes with every estimate
            dt = acc.proposal
        elif acc.halvings:
            dt = step  # a halved step stays halved
        integ.commit(x, step)
        integ.t = ts.end_time(integ.t, t_end, nominal)
        flow = integ.flow()
        flow.step = StepInfo(t=integ.t, dt=step, iterations=its, error=err, rejected=rejected,
                             refreshes=refreshes, wall_time={"step": time.perf_counter() - t0})
        yield integ.t, flow
