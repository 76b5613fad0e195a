"""The paper's partitioned (staggered) coupling, kept for comparison.

Each step: the particle velocities are predicted (held pressures and forces),
the fluid is solved with them as Dirichlet data ``u = V + omega x (x - X)``
on the core outlines, the consistent fluid force then drives the particle
corrector ``m (a0 V + a1 V_n + a2 V_{n-1}) = F_fluid + F_ext``. Optional
sub-iterations with under-relaxation repeat the fluid solve with the
corrected velocities. Cheap (the fluid matrix never changes), but unstable
when the particles are light: the added-mass effect makes the explicit
force-velocity exchange amplify errors by about ``C_a rho_f / rho_p`` per
iteration. The divergence is detected and reported as a
:class:`~skfem_granular.fluid.ConvergenceError`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..fluid.errors import ConvergenceError
from ..fluid.factor_cache import FactorCache
from ..fluid.linsolve import make_solver
from ..fluid.newton import newton_iterate
from .problem import StepProblem, StepSolution
from .rigid import CorrectorOptions, RigidBodies, RigidParticles


@dataclass(frozen=True)
class Staggering:
    """The staggered scheme's iteration.

    Attributes
    ----------
    subiterations : int
        Fluid solves per step (1 = the plain explicit scheme).
    relaxation : float or "aitken"
        Under-relaxation of the particle velocity between sub-iterations, in (0, 1];
        ``"aitken"``: dynamic Aitken Delta^2 relaxation.
    coupling_tol : float
        Sub-iterations stop when the particle velocity changes by less than this,
        relative to the velocity scale.
    """

    subiterations: int = 20
    relaxation: float | str = "aitken"
    coupling_tol: float = 1e-8

    def __post_init__(self):
        r = self.relaxation
        if r != "aitken" and not 0.0 < float(r) <= 1.0:
            raise ValueError(f"relaxation = {r!r}: must be 'aitken' or in (0, 1]")


class PartitionedCoupling(RigidParticles):
    """Staggered fluid-particle coupling; same interface as :class:`MonolithicCoupling`.

    Parameters
    ----------
    space, fluid, walls, bodies, convection, terms
        As for :class:`MonolithicCoupling` (particles with a prescribed motion: their
        velocities are the fluid's boundary data, no corrector).
    corrector : CorrectorOptions, optional
        The fluid solves' linear solver, tolerance (default 1e-9) and iteration limit.
    staggering : Staggering, optional
        Sub-iterations, relaxation and their tolerance.
    """

    def __init__(self, space, fluid, walls: dict, bodies: RigidBodies, *,
                 convection: bool = True, corrector: CorrectorOptions | None = None,
                 staggering: Staggering | None = None, terms=None):
        super().__init__(space, fluid, walls, bodies, convection=convection, terms=terms)
        corrector = CorrectorOptions(newton_tol=1e-9) if corrector is None else corrector
        staggering = Staggering() if staggering is None else staggering
        self.subiterations = int(staggering.subiterations)
        self.relaxation = staggering.relaxation
        self.coupling_tol = float(staggering.coupling_tol)
        self.newton_tol = corrector.newton_tol
        self.max_iterations = corrector.max_iterations
        self.solver = make_solver(corrector.solver, self.op.free.size)
        self.factors = FactorCache(self.solver, self.op.reduced_bdf2_system, self.timings)

    def _boundary_values(self, x, xi, t):
        if self.wall_dirichlet is not None:
            d = self.wall_dirichlet.dofs
            x[d] = self.wall_dirichlet.values(t)[d]
        for k in range(self.K):
            d, c, lever = self.levers(k)
            x[d] = np.where(c == 0, xi[0, k], xi[1, k]) + xi[2, k] * lever
        if self.op.pinned:
            x[self.space.nu] = 0.0

    def _fluid_solve(self, x, rhs_u, scale):
        op = self.op
        A_uu = self.factors.A_uu

        def stop(it, dx, x):
            return op.linear or float(np.abs(dx).max()) <= self.newton_tol * max(
                scale, np.abs(x[: self.space.nu]).max())

        it = newton_iterate(x, lambda x: op.residual(x, rhs_u=rhs_u, A_uu=A_uu),
                            lambda x, R, it: -self.solver.solve(R[op.free]), stop,
                            max_iterations=self.max_iterations, index=op.free)
        if it is None:
            raise ConvergenceError("partitioned coupling: fluid corrector did not converge")
        return it

    def step(self, problem: StepProblem) -> StepSolution:
        """One staggered step (``problem.xi_imposed`` as for the monolithic coupling: the
        imposed particles' velocities at ``t_new``); a moving mesh is not supported."""
        pr = problem
        imposed = self.imposed if self.imposed.any() else None
        if imposed is not None and pr.xi_imposed is None:
            raise ValueError("PartitionedCoupling.step: xi_imposed (3, K) is required: the "
                             "coupling has particles with a prescribed motion")
        sp_, op = self.space, self.op
        op.time = pr.t_new  # where the user terms are assembled
        self.factors.operator(pr.bdf2.a0)
        rhs_u = -self.fluid.density * (sp_.M @ pr.bdf2.history(pr.u_n, pr.u_prev))
        # predictor: velocities extrapolated with pressures and forces held
        f = pr.bdf2
        xi = (pr.xi_n if pr.xi_prev is None or f.dt_prev is None
              else pr.xi_n + (pr.dt / f.dt_prev) * (pr.xi_n - pr.xi_prev))
        if not self.rotation:
            xi = xi.copy()
            xi[2] = 0.0
        if imposed is not None:
            xi = xi.copy()
            xi[:, imposed] = np.asarray(pr.xi_imposed, dtype=float)[:, imposed]
        x = np.zeros(sp_.N)
        x[: sp_.nu] = pr.u_n
        if pr.p_guess is not None:
            x[sp_.nu :] = pr.p_guess
        t0 = time.perf_counter()
        xi_new, F, T, its = self._subiterate(x, xi, rhs_u, pr)
        self.timings["solve"] += time.perf_counter() - t0
        self._last = (rhs_u, x, None)
        return StepSolution(x=x, xi=xi_new, force=F, torque=T, iterations=its)

    def _subiterate(self, x, xi, rhs_u, pr: StepProblem):
        """Fluid solves with the particle velocities ``xi`` as boundary data, the particle
        corrector driven by their force, relaxed until the velocities agree; ``x`` is
        updated in place. Returns ``(xi, F, T, fluid iterations)``."""
        op, imposed = self.op, (self.imposed if self.imposed.any() else None)
        hist_xi = pr.bdf2.history(pr.xi_n, pr.xi_prev)
        m3 = np.stack([self.mass, self.mass, self.inertia])
        ext = np.vstack([pr.F_ext, pr.T_ext[None, :]])
        scale = pr.velocity_scale()
        its = 0
        changes: list[float] = []
        omega = 0.5 if self.relaxation == "aitken" else float(self.relaxation)
        r_old = None
        for sub in range(max(1, self.subiterations)):
            self._boundary_values(x, xi, pr.t_new)
            try:
                its += self._fluid_solve(x, rhs_u, scale)
            except ConvergenceError:
                self._diverged(pr.t_new, xi)
            F, T = self.fluid_forces(op.residual(x, rhs_u=rhs_u, A_uu=self.factors.A_uu))
            xi_new = ((ext + np.vstack([F, T[None, :]])) / m3 - hist_xi) / pr.bdf2.a0
            if not self.rotation:
                xi_new[2] = 0.0
            if imposed is not None:
                xi_new[:, imposed] = xi[:, imposed]
            r = (xi_new - xi).ravel()
            changes.append(float(np.abs(r).max()))
            # the fixed-point map amplifies by ~C_a rho_f / rho_p: growing changes = divergence
            if not np.all(np.isfinite(xi_new)) or (
                len(changes) >= 4 and changes[-1] > changes[-2] > changes[-3] > changes[-4]
            ):
                self._diverged(pr.t_new, xi_new)
            if changes[-1] <= self.coupling_tol * max(scale, float(np.abs(xi_new).max())):
                return xi_new, F, T, its
            if sub == 0 and self.relaxation != "aitken":
                xi = xi_new
                continue
            if self.relaxation == "aitken" and r_old is not None:
                dr = r - r_old
                omega = -omega * float(r_old @ dr) / max(float(dr @ dr), 1e-300)
            r_old = r
            xi = xi + omega * r.reshape(xi.shape)
        if self.subiterations > 1:
            raise ConvergenceError(
                f"partitioned coupling at t={pr.t_new:.6g}: not converged in "
                f"{self.subiterations} sub-iterations (last change {changes[-1]:.2e}); the "
                "added-mass effect of light particles: use the monolithic coupling")
        return xi_new, F, T, its

    @staticmethod
    def _diverged(t, xi):
        raise ConvergenceError(
            f"partitioned coupling diverged at t={t:.6g} (|V| = {np.abs(xi).max():.3g}): the "
            "added-mass instability of light particles; use the monolithic coupling"
        )
