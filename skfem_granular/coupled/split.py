"""The split coupling: a pressure-correction step with the rigid bodies inside the projection.

:class:`SplitCoupling` solves one coupled BDF2 step without factorising the coupled
saddle-point matrix. In the unknowns ``z = (u_free, xi)`` of
:class:`~skfem_granular.coupled.reduced.ReducedRigid` (``u = E z + x_D``):

1. **Predictor.** With the pressure extrapolated (``p# = p_n + w (p_n - p_{n-1})``,
   ``p_n`` alone after a remesh) and the convection linearised at the extrapolated
   velocity ``u*`` (Oseen), the system ``[E^T (a0 rho M + eta K + rho N(u* - w)) E + a0
   M_b] z~ = ...`` for the fluid velocity and the grains' rigid velocities together (the
   viscous coupling implicit), by BiCGStab with a Jacobi preconditioner, matrix-free
   (conjugate gradients for Stokes on a fixed mesh: then it is symmetric).
2. **Projection** (:mod:`~skfem_granular.coupled.rigid_projection`). With ``H = c rho
   diag(M)``, ``C = B E_Gamma`` (the pressure's coupling to the grains' rigid modes) and
   ``M_eff = M_b + E_Gamma^T H E_Gamma``::

       [ B_i H_i^-1 B_i^T   C      ] [psi]   [B u~]
       [ C^T               -M_eff  ] [ y ] = [ 0  ]

   then ``u_i = u~_i - H_i^-1 B_i^T psi`` and ``xi = xi~ - y``: the step's velocity is
   discretely divergence-free and the added mass is implicit (light grains stay stable).
   The matrix does not depend on the step: it is factorised once per mesh (the mesh as
   built) and serves, as the preconditioner of GMRES, while the mesh moves.
3. **Pressure**, rotational form: ``p = p# + a0 psi - 2 eta Pi(div u~)`` (the factor 2 of
   the symmetric-gradient viscous form).
4. **Forces**: each grain's own momentum balance ``M_b (a0 xi + a1 xi_n + a2 xi_{n-1})
   - F_ext``, which is the split's reaction force: fluid and grains exchange exactly
   opposite momenta.

Where the parts come from: the algebraic (discrete) incremental pressure correction of
Perot (1993) and Quarteroni, Saleri and Veneziani (2000); the rotational form of
Timmermans, Minev and Van De Vosse (1996) and Guermond and Shen (2004); the rigid
bodies' velocities implicit in the projection, as in the added-mass partitioned schemes
of Fernandez, Gerbeau and Grandmont (2007) and Banks, Henshaw, Schwendeman and Tang
(2017). The lumping factor, the pressure extrapolation and the stability for light
grains were chosen by measurement (the design page).

On a moving mesh (ALE) the geometry of the step is explicit: the mesh is put where the
extrapolated rigid velocities put the grains before the predictor, and where the solved
ones put them at the end.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .problem import StepProblem, StepSolution
from .reduced import ReducedRigid
from .rigid import RigidBodies
from .rigid_projection import RigidProjection, krylov

#: The factor of the rotational pressure term (2: symmetric-gradient viscous form).
ROTATIONAL = 2.0


@dataclass(frozen=True)
class SplitOptions:
    """How the split coupling solves its two systems.

    Attributes
    ----------
    predictor_rtol : float
        Relative residual (of the step's residual at the extrapolated state) at which the
        predictor's BiCGStab (conjugate gradients for Stokes on a fixed mesh) stops. The
        default 1e-4 changes the paper's particle and a 30-grain column by less than 1e-4
        of their difference from the monolithic run and cuts a 1000-grain step's
        iterations from 23 to 7 (docs/benchmarks.md, "The predictor's tolerance"); 1e-3
        starts to shift the sinking particle's splitting error, 1e-2 loses its order.
    projection_rtol : float
        Relative residual at which GMRES on a moved mesh's projection stops.
    max_iterations : int
        Iteration limit of either (a step that reaches it fails and is halved).
    refactor_after : int
        The projection is factorised anew, on the mesh where a step ends, after a step
        whose GMRES needed more than this many iterations with the held factors.
    start_tol, start_iterations, start_krylov : float, int, int
        A step with no pressure to start from (a run's first) is solved by Newton's
        method (GMRES preconditioned with the split pass) until its update is below
        ``start_tol`` of the velocity scale, in at most ``start_iterations`` Newton
        iterations (0: one pass, as other steps) of at most ``start_krylov`` GMRES
        iterations (the Newton iterations stop at a GMRES that reaches it).
    newton_rtol : float
        Relative residual at which GMRES stops in each of those Newton iterations.
    """

    predictor_rtol: float = 1e-4
    projection_rtol: float = 1e-8
    max_iterations: int = 500
    refactor_after: int = 12
    start_tol: float = 1e-6
    newton_rtol: float = 1e-4
    start_iterations: int = 10
    start_krylov: int = 10


class SplitCoupling(ReducedRigid):
    """Fluid + rigid particles by pressure correction, the rigid velocities implicit.

    Parameters
    ----------
    space, fluid, walls, bodies, convection, terms
        As :class:`~skfem_granular.coupled.monolithic.MonolithicCoupling`. User terms
        enter the predictor explicitly (at the extrapolated velocity).
    options : SplitOptions, optional
    """

    uses_pressure_history = True

    def __init__(self, space, fluid, walls: dict, bodies: RigidBodies, *,
                 convection: bool = True, options: SplitOptions | None = None, terms=None):
        super().__init__(space, fluid, walls, bodies, convection=convection, terms=terms)
        self.options = SplitOptions() if options is None else options
        o = self.options
        self.projection = RigidProjection(self, o.projection_rtol, o.max_iterations,
                                          o.refactor_after)
        self.predictor_iterations = 0

    # ------------------------------------------------------------------ the stepper's calls
    @property
    def counts(self) -> dict:
        """Projection factorisations, predictor and projection iterations so far."""
        return {"factorizations": self.projection.factorizations,
                "predictor_iterations": self.predictor_iterations,
                "projection_iterations": self.projection.iterations}

    def factor_counts(self) -> dict:
        """Projection factorisations on this mesh (``jacobian_refreshes``: always 0)."""
        return {"factorizations": self.counts["factorizations"], "jacobian_refreshes": 0}

    def inherit_factor_kind(self, old) -> None:
        """Nothing to inherit: the split has one kind of factorisation."""

    @property
    def chord_extra_iterations(self) -> int:
        """No chord iteration: 0."""
        return 0

    @chord_extra_iterations.setter
    def chord_extra_iterations(self, value: int) -> None:
        pass

    def held_block(self):
        """None: the split holds no factorisation of a velocity block."""
        return None

    def forget_factorization(self) -> None:
        """Factorise the projection anew on the next step."""
        self.projection.forget()

    def factor_record(self) -> dict:
        """Where the projection's factorisation was made (``factor_a0`` 1.0 marks one;
        None: none held), for a checkpoint."""
        held = self.projection.record()
        if held is None:
            return {"factor_a0": None, "factor_nodes": None, "factor_centers": None,
                    "factor_x": None, "factor_w": None}
        return {"factor_a0": 1.0, "factor_nodes": held[0], "factor_centers": held[1],
                "factor_x": None, "factor_w": None}

    def refactor(self, record: dict, reference_space) -> None:
        """Factorise the projection where :meth:`factor_record` says it was."""
        if record.get("factor_a0") is None:
            return
        self.move(reference_space.moved(record["factor_nodes"]), record["factor_centers"],
                  None)
        self.projection.factorize()

    # ------------------------------------------------------------------ the predictor
    def _jacobi(self, A: sp.spmatrix, a0: float) -> np.ndarray:
        """The diagonal of ``E^T A E + a0 M_b`` (velocity-like unknowns), once a step."""
        nu, nf = self.space.nu, self.n_ufree
        diag = np.empty(self.nu_z)
        diag[:nf] = A.diagonal()[self.u_free]
        E_G = self.E[:nu, self.rigid_slice]
        diag[nf:] = (np.asarray(E_G.multiply(A @ E_G).sum(axis=0)).ravel()
                     + a0 * self.inertia_diag())
        return diag

    def _predictor(self, ctx: _StepContext, G: np.ndarray) -> np.ndarray:
        """The correction ``dz`` solving ``[E^T P E + a0 M_b] dz = -G`` (velocity-like
        unknowns, ``P`` the step's predictor matrix), Jacobi-preconditioned: by conjugate
        gradients, or BiCGStab when ``P`` holds the convection."""
        A, diag, symmetric = ctx.P, ctx.jacobi, ctx.P is ctx.A
        nu, n, nf = self.space.nu, self.nu_z, self.n_ufree
        rigid = ctx.a0 * self.inertia_diag()
        z = np.zeros(self.nz)
        x = np.zeros(self.space.N)

        def matvec(v):
            z[:n] = v
            x[:nu] = A @ (self.E @ z)[:nu]
            out = (self.ET @ x)[:n]
            out[nf:] += rigid * v[nf:]
            return out

        op = spla.LinearOperator((n, n), matvec=matvec)
        pre = spla.LinearOperator((n, n), matvec=lambda v: v / diag)
        rtol, maxiter = self.options.predictor_rtol, self.options.max_iterations
        if symmetric:
            dz, its = krylov(spla.cg, op, -G, pre, rtol, maxiter)
        else:
            dz, its = krylov(spla.bicgstab, op, -G, pre, rtol, maxiter, strict=False)
            if np.linalg.norm(G + op @ dz) > rtol * np.linalg.norm(G):  # a breakdown
                dz, more = krylov(spla.gmres, op, -G, pre, rtol, maxiter, x0=dz, restart=50,
                                   callback_type="pr_norm")
                its += more
        self.predictor_iterations += its
        return dz

    # ------------------------------------------------------------------ the step
    def step(self, problem: StepProblem) -> StepSolution:
        """One split BDF2 (or backward-Euler) step of fluid and rigid particles.

        The pressure is extrapolated linearly from ``t_{n-1}`` and ``t_n`` on backward-Euler
        (contact) steps too: holding it there instead made a 100-grain immersed column's
        mean grain velocity 4 % slower after 30 steps than the monolithic run's, ten times
        the monolithic run's own change when the step is halved, and halving the step did
        not reduce the difference; extrapolated, it is 0.02 %. After a remesh (no pressure
        at ``t_{n-1}`` on the mesh) the pressure of ``t_n`` is held. A step without any
        pressure to start from (a run's first)
        would start its grains with the lumped projection's added mass, wrong by 10-20 %:
        it is solved to the monolithic step (:meth:`_converge`).
        """
        pr = problem
        t0 = time.perf_counter()
        a0 = pr.bdf2.a0
        self.impose(pr.xi_imposed, pr.xi_n, pr.xi_guess)
        self.reference_op.time = self.op.time = pr.t_new
        u_star, xi_star, p_hat = _extrapolate(pr, self.space.N - self.space.nu)
        if self.xi_imposed is not None:
            xi_star[:, self.imposed] = self.xi_imposed[:, self.imposed]
        self._follow(pr.geometry, xi_star)
        ctx = _StepContext(
            a0=a0, A=self.op.velocity_block(a0),
            rhs_u=-self.fluid.density * (self.space.M @ pr.bdf2.history(pr.u_n, pr.u_prev)),
            rigid_rhs=self.rigid_rhs(pr.bdf2.history(pr.xi_n, pr.xi_prev), pr.F_ext,
                                      pr.T_ext),
            x_D=self.imposed_values(self.x_dirichlet(pr.t_new), self.xi_imposed))
        z = self.first_iterate(u_star, p_hat, xi_star)
        ctx = self._with_convection(ctx, z)
        ctx = replace(ctx, jacobi=self._jacobi(ctx.P, a0))
        self.timings["assembly"] += time.perf_counter() - t0
        t1 = time.perf_counter()
        div = self._correct(z, p_hat, ctx)
        iterations = 1
        cold = pr.p_guess is None and self.options.start_iterations > 0
        if cold:
            iterations += self._converge(z, p_hat, ctx, pr)
        self.timings["solve"] += time.perf_counter() - t1
        t2 = time.perf_counter()
        xi = self.rigid(z)
        x = self.E @ z + ctx.x_D
        x[self.space.nu:] = self._pressure(p_hat, None if cold else div)
        F, T = self._forces(pr, xi, x, ctx)
        self._follow(pr.geometry, xi)  # the mesh where the solved velocities put the grains
        if self.projection.refactor_due:  # here, so that a checkpoint's record holds where
            self.projection.factorize()
        self._last = (ctx.rhs_u, x, ctx.A)
        self.timings["forces"] += time.perf_counter() - t2
        return StepSolution(x=x, xi=xi, force=F, torque=T, iterations=iterations)

    def _with_convection(self, ctx: _StepContext, z: np.ndarray) -> _StepContext:
        """``ctx`` with the predictor's matrix: the velocity block with the convection
        linearised at the extrapolated velocity (Oseen, ``rho N(u* - w)``), so that the
        convection is semi-implicit. Explicit convection blew up a 400-grain immersed
        column after 21 steps of 0.2 ms: the flow in the lined gaps (0.1-0.2 m/s on
        elements of a few micrometres) has a convective Courant number above 1."""
        if not self.op.convection and self.w_mesh is None:
            return ctx
        x = self.E @ z + ctx.x_D
        # its exact zeros kept: dropping them was 15 % of a 1000-grain run's time, and
        # the matrix only multiplies
        P = self.op.velocity_jacobian(x, ctx.a0, newton=False, w_mesh=self.w_mesh,
                                      keep_zeros=True)
        return replace(ctx, P=P)

    def _follow(self, geometry, xi: np.ndarray) -> None:
        """Move the mesh where rigid velocities ``xi`` put the grains (moving mesh)."""
        if geometry is not None:
            g = geometry(xi)
            if g is not None:
                self.move(*g)

    def _residual(self, z: np.ndarray, p_hat: np.ndarray, ctx: _StepContext):
        """The coupled residual ``(G, Rf, x)`` at ``(z, p_hat)``: ``G`` on the unknowns
        ``z`` (velocity-like rows, then the free pressures), ``Rf`` the fluid's."""
        nu, n, nf = self.space.nu, self.nu_z, self.n_ufree
        x = self.E @ z + ctx.x_D
        x[nu:] = p_hat
        Rf = self.op.residual(x, rhs_u=ctx.rhs_u, A_uu=ctx.A, w_mesh=self.w_mesh)
        G = self.ET @ Rf
        G[nf:n] += ctx.a0 * self.inertia_diag() * z[nf:n] - ctx.rigid_rhs
        return G, Rf, x

    def _split_solve(self, G: np.ndarray, ctx: _StepContext):
        """One predictor-projection pass: the approximate solution ``(dz, dp)`` of the
        coupled system for the residual ``-G`` (``dz`` velocity-like, ``dp`` all pressure
        DOFs), and ``B u~ - B u`` of the predicted correction."""
        nu, n, nf = self.space.nu, self.nu_z, self.n_ufree
        dz = self._predictor(ctx, G[:n])
        ddiv = self.space.B @ (self.E @ np.concatenate([dz, np.zeros(self.nz - n)]))[:nu]
        r = ddiv[self.p_free - nu] + G[n:]
        psi_free, y, H = self.projection.solve(r)
        psi = np.zeros(self.space.N - nu)
        psi[self.p_free - nu] = psi_free
        dz[:nf] -= (self.space.B.T @ psi)[self.u_free] / H[self.u_free]
        dz[nf:] -= y
        return dz, ctx.a0 * psi, ddiv

    def _correct(self, z: np.ndarray, p_hat: np.ndarray, ctx: _StepContext):
        """One predictor-projection pass on the coupled residual at ``(z, p_hat)``, both
        updated in place (the pressure without the rotational term).

        Returns ``B u~`` (all pressure DOFs) of the predicted velocity ``u~``.
        """
        G, Rf, _ = self._residual(z, p_hat, ctx)
        dz, dp, ddiv = self._split_solve(G, ctx)
        z[: self.nu_z] += dz
        p_hat += dp
        return Rf[self.space.nu:] + ddiv

    def _converge(self, z: np.ndarray, p_hat: np.ndarray, ctx: _StepContext,
                  pr: StepProblem) -> int:
        """Newton's method on the coupled step from ``(z, p_hat)`` (updated in place), each
        linear system by GMRES preconditioned with the split pass, until the update is
        below ``start_tol`` of the velocity scale (the monolithic step) or GMRES reaches
        ``start_krylov`` iterations (many grains: the split's start is then improved, not
        converged). Returns the GMRES iterations."""
        nu, n, nz = self.space.nu, self.nu_z, self.nz
        p_rows = self.p_free - nu
        rigid = ctx.a0 * self.inertia_diag()
        total = 0
        for _ in range(self.options.start_iterations):
            G, _, x = self._residual(z, p_hat, ctx)

            def jacobian(w, x=x):
                d = self.E @ w
                out = self.ET @ self.op.jacobian_action(x, d, ctx.A, w_mesh=self.w_mesh)
                out[self.n_ufree:n] += rigid * w[self.n_ufree:n]
                return out

            def precondition(r):
                dz, dp, _ = self._split_solve(-r, ctx)
                return np.concatenate([dz, dp[p_rows]])

            J = spla.LinearOperator((nz, nz), matvec=jacobian)
            M = spla.LinearOperator((nz, nz), matvec=precondition)
            w, its = krylov(spla.gmres, J, -G, M, self.options.newton_rtol,
                             1, strict=False, restart=self.options.start_krylov,
                             callback_type="pr_norm")  # one cycle: start_krylov at most
            total += its
            z[:n] += w[:n]
            p_hat[p_rows] += w[n:]
            change = float(np.abs(w[:n]).max())
            if its >= self.options.start_krylov or change <= self.options.start_tol * max(
                    pr.velocity_scale(), float(np.abs(z[:n]).max())):
                break
        return total

    def _pressure(self, p_hat: np.ndarray, div: np.ndarray | None) -> np.ndarray:
        """The pressure at the end of the step: ``p_hat`` with the rotational term of the
        predicted velocity's divergence ``div`` (None: none, a converged restart)."""
        p = p_hat
        if div is not None:
            lumped = np.asarray(self.space.Mp.sum(axis=1)).ravel()
            p = p_hat + ROTATIONAL * self.fluid.viscosity * div / lumped
        if self.op.pinned:
            p = p - p[0]
        return p

    def _forces(self, pr: StepProblem, xi: np.ndarray, x: np.ndarray,
                ctx: _StepContext) -> tuple[np.ndarray, np.ndarray]:
        """Fluid force ``(2, K)`` and torque ``(K,)``: the free grains' momentum balance
        (the split's reaction); on imposed grains the reaction of the fluid's residual at
        the end of the step."""
        F, T = np.zeros((2, self.K)), np.zeros(self.K)
        if self.imposed.any():
            F, T = self.fluid_forces(self.op.residual(x, rhs_u=ctx.rhs_u, A_uu=ctx.A,
                                                      w_mesh=self.w_mesh))
        free = self.free_particles
        m3 = np.stack([self.mass, self.mass, self.inertia])
        balance = m3 * pr.bdf2.derivative(xi, pr.xi_n, pr.xi_prev)
        F[:, free] = balance[:2, free] - pr.F_ext[:, free]
        T[free] = balance[2, free] - pr.T_ext[free]
        return F, T


@dataclass(frozen=True)
class _StepContext:
    """What every pass of one step shares: ``a0``, the velocity block ``A`` (of the
    residual), the predictor's ``P`` (``A`` with the linearised convection) and its
    Jacobi diagonal, the histories' right-hand sides and the Dirichlet values."""

    a0: float
    A: sp.csr_matrix
    rhs_u: np.ndarray
    rigid_rhs: np.ndarray
    x_D: np.ndarray
    P: sp.csr_matrix | None = None
    jacobi: np.ndarray | None = None

    def __post_init__(self):
        if self.P is None:  # the predictor's matrix: the velocity block without convection
            object.__setattr__(self, "P", self.A)


def _extrapolate(pr: StepProblem, n_p: int):
    """``(u*, xi*, p#)``: velocities extrapolated to the end of the step (linearly, as the
    first guess of the step), the pressure extrapolated linearly from ``p_prev`` (held
    without it, zero without any)."""
    u = np.array(pr.u_n if pr.u_guess is None else pr.u_guess, dtype=float)
    xi = np.array(pr.xi_n if pr.xi_guess is None else pr.xi_guess, dtype=float)
    p = np.zeros(n_p) if pr.p_guess is None else np.array(pr.p_guess, dtype=float)
    if pr.p_guess is not None and pr.p_prev is not None and pr.dt_prev is not None:
        w = pr.bdf2.dt / pr.dt_prev
        p = p + w * (p - pr.p_prev)
    return u, xi, p
