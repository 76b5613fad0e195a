"""Fluid-particle coupling: the BDF2 corrector of the paper's Eq. 1 with rigid particles.

This is the one module that knows both the fluid (a mesh, P2/P1 DOFs) and
the particles (rigid-body velocities ``V``, ``omega``, masses, forces).

:class:`MonolithicCoupling` (the default) expresses the velocity DOFs on each
particle's core outline through the particle's rigid DOFs ``xi = (Vx, Vy,
omega)`` with a sparse prolongation ``E`` (``u = V + omega x (x - X)`` at
every boundary node), and solves fluid and particles in one system::

    E^T R_f(E z + x_D) + [0; m (a0 V + a1 V_n + a2 V_{n-1}) - F_ext] = 0,

whose Jacobian is ``E^T J_f E + a0 diag(m, m, I)``. The fluid force on a
particle is the consistent (reaction) force ``-P_k^T R_f``; it comes out of
the solve, so the scheme is stable for every density ratio (no added-mass
instability). Particles with a prescribed motion have no rigid DOFs in ``z``:
their boundary values ``V + omega x (x - X)`` are known and go into ``x_D``, and
their force is the same reaction ``-P_k^T R_f``. :class:`PartitionedCoupling` is
the paper's explicit scheme:
particle velocities from the DEM are Dirichlet data of a fluid solve whose
force then drives the DEM step.

On a moving mesh (ALE, :meth:`MonolithicCoupling.move`; the default) the
outline nodes are where the particles are at the end of the step, inside the
iteration (``step(geometry=...)``). On a fixed mesh the outline nodes keep the
positions they had when the mesh was built and the rigid velocities are taken
about that reference centre (the nodes are the particle's material points
shifted back by the displacement since the last remesh); the stepper remeshes
before that lag grows past a fraction of the element size
(:mod:`skfem_granular.coupled.transfer`).

The corrector is a chord iteration on the factorised BDF2-Stokes matrix; when it
stalls (:class:`~skfem_granular.fluid.newton.ChordStall`, the rule of the fluid's
integrator too) the coupled Newton Jacobian is factorised at the iterate and the
iteration continues on it (later steps with the same ``a0`` reuse it). A
factorisation made anew for a new ``a0`` is of the Newton Jacobian at the step's
first iterate when the one it replaces was one (:data:`KEEP_NEWTON_OPERATOR`), and so
is a new mesh's when the stepper carries the kind over (a mesh replaced within a few
steps: :data:`~skfem_granular.coupled.mesh_keeper.NEWTON_CARRY_STEPS`). GMRES
preconditioned by the held factorisation instead was measured on the collapse's
contact phase: 12-25 iterations per correction, as costly as a new SuperLU
factorisation at 20k unknowns.
"""

from __future__ import annotations

import time
import weakref

import numpy as np
import scipy.sparse as sp

from ..fluid.errors import ConvergenceError
from ..fluid.factor_cache import FactorCache
from ..fluid.linsolve import make_solver
from ..fluid.newton import ChordStall, chord_converged, newton_iterate
from .problem import StepProblem, StepSolution
from .reduced import ReducedRigid
from .rigid import CorrectorOptions, RigidBodies

#: A factorisation made anew (new ``a0``; a new mesh the stepper marks so) is of the Newton
#: Jacobian at the first iterate when the last one was (``False``: of the linear BDF2-Stokes
#: operator always, the stall rule refreshing it as needed).
KEEP_NEWTON_OPERATOR = True


class MonolithicCoupling(ReducedRigid):
    """Fluid + rigid particles in one BDF2/Newton system on a fixed mesh.

    Parameters
    ----------
    space : TaylorHood
        Discretisation of the fluid mesh; particle ``k`` is the boundary
        ``"particle{k}"``, the rest of the named boundaries listed in
        ``walls`` carry fixed velocities.
    fluid : Fluid
    walls : dict
        ``{boundary name: velocity spec}`` of the fixed walls.
    bodies : RigidBodies
        The particles (reference centres, masses, inertias); particles with a
        prescribed motion have no rigid DOFs in the system (their boundary values are
        Dirichlet data, ``StepProblem.xi_imposed``), the fluid force on them is the same
        consistent reaction ``-P_k^T R_f``; without ``rotation`` ``omega = 0``.
    convection : bool
        Navier-Stokes or unsteady Stokes.
    corrector : CorrectorOptions, optional
        Linear solver, and the iterations' tolerance (relative to the velocity scale)
        and limit.
    terms : UserTerms, optional
        scikit-fem forms added to the fluid equations
        (:class:`~skfem_granular.fluid.user_terms.UserTerms`), assembled at ``t_new`` on
        the mesh of each iterate; the chord operator holds their matrices where it was
        factorised, and a step iterates to ``newton_tol`` even for Stokes.
    """

    def __init__(self, space, fluid, walls: dict, bodies: RigidBodies, *,
                 convection: bool = True, corrector: CorrectorOptions | None = None,
                 terms=None):
        super().__init__(space, fluid, walls, bodies, convection=convection, terms=terms)
        corrector = CorrectorOptions() if corrector is None else corrector
        self.newton_tol = corrector.newton_tol
        self.max_iterations = corrector.max_iterations
        # rigid-body velocities couple to every element at their particle: nested dissection
        # puts them in the separator where those elements part
        self._ordering = space.ordering(self.E)
        self.solver = make_solver(corrector.solver, self.nz)
        # the cache holds the assembly through a weak reference: a bound method would make
        # coupling -> cache -> coupling a cycle, and a remeshed-away coupling (its blocks,
        # its factorisation) would stay in memory until Python's cyclic collector ran
        assemble = weakref.WeakMethod(self._coupled_system)

        def system(a0: float):
            method = assemble()
            assert method is not None  # the cache is the coupling's: it lives while called
            return method(a0)

        self.factors = FactorCache(self.solver, system, self.timings)
        # (vertex positions, centres, fluid state and mesh velocity of a Newton Jacobian) of
        # the last factorisation
        self.factorized_on: tuple[np.ndarray, np.ndarray, np.ndarray | None,
                                  np.ndarray | None] | None = None

    # ------------------------------------------------------------------ algebra
    def _coupled_system(self, a0: float, x: np.ndarray | None = None):
        """``E^T J E + a0 diag(m, m, I)`` for the factorisation cache: ``J`` the BDF2-Stokes
        matrix, or with ``x`` (full fluid vector) the Newton Jacobian there, the convection
        linearised (``((u - w) . grad) du + (du . grad) u`` on a moving mesh)."""
        # where the mesh was when factorised (a moved mesh's checkpoint rebuilds it there)
        w = self.w_mesh
        self.factorized_on = (self.space.mesh.p, self.centers.copy(),
                              None if x is None else np.array(x, dtype=float),
                              None if x is None or w is None else np.array(w, dtype=float))
        A_uu = self.op.velocity_block(a0)
        J = self.op.linear_matrix(A_uu) if x is None else self.op.jacobian(x, a0, w_mesh=w)
        Jz = (self.ET @ J @ self.E).tocsr()
        diag = np.zeros(self.nz)
        diag[self.rigid_slice] = a0 * self.inertia_diag()
        Jz = (Jz + sp.diags(diag)).tocsr()
        # sorted in place: the solver keeps a canonical matrix as it is, where it would
        # copy and sort it (the peak, SuperLU's, measured the same either way)
        Jz.sum_duplicates()
        sp_ = self.space
        pf = self.E[sp_.nu:, self.nu_z:].nonzero()[0]
        Mp = sp_.Mp[np.sort(pf)][:, np.sort(pf)]
        return A_uu, Jz, self.nu_z, dict(Mp=Mp, ordering=self._ordering)

    def factorize_jacobian(self, x: np.ndarray, a0: float) -> None:
        """Factorise the coupled Newton Jacobian at the fluid state ``x`` (full vector) on
        the mesh in use (with its mesh velocity) and hold it as the chord operator for
        ``a0`` (:meth:`FactorCache.factorize_system`); :attr:`factorized_on` records
        where, so that a checkpoint can rebuild it."""
        t0 = time.perf_counter()
        system = self._coupled_system(a0, x)
        self.timings["assembly"] += time.perf_counter() - t0
        self.factors.factorize_system(a0, system)

    def refactor(self, record: dict, reference_space) -> None:
        """Make again the factorisation a :meth:`factor_record` describes, on
        ``reference_space`` moved to its vertices (nothing when the record is empty): a
        moved mesh's factorisation depends on where the mesh was when it was made."""
        if record.get("factor_a0") is None:
            return
        self.move(reference_space.moved(record["factor_nodes"]), record["factor_centers"],
                  record["factor_w"])
        if record["factor_x"] is None:
            self.factors.operator(record["factor_a0"])
        else:
            self.factorize_jacobian(record["factor_x"], record["factor_a0"])

    def residual(self, z, x_D, rhs_u, rigid_rhs, A_uu=None):
        """Coupled residual and the fluid residual behind it (``A_uu``: the velocity block
        to use, default the factorised one's; a moved mesh passes its own)."""
        x = self.E @ z + x_D
        A_uu = self.factors.A_uu if A_uu is None else A_uu
        Rf = self.op.residual(x, rhs_u=rhs_u, A_uu=A_uu, w_mesh=self.w_mesh)
        G = self.ET @ Rf
        G[self.rigid_slice] += (self.factors.a0 * self.inertia_diag() * z[self.rigid_slice]
                                - rigid_rhs)
        return G, Rf, x

    def step(self, problem: StepProblem) -> StepSolution:
        """Solve one BDF2 (or backward-Euler) step of fluid and rigid particles.

        On a moving mesh (``problem.geometry``) the mesh is put where the iterate puts the
        particles before every residual evaluation, so the positions at the end of the
        step are part of the iteration (the chord operator stays the factorised one).
        """
        pr = problem
        xi_guess = self.impose(pr.xi_imposed, pr.xi_n, pr.xi_guess)
        a0 = pr.bdf2.a0
        self.reference_op.time = self.op.time = pr.t_new  # where user terms are assembled
        hist_u = pr.bdf2.history(pr.u_n, pr.u_prev)
        rigid_rhs = self.rigid_rhs(pr.bdf2.history(pr.xi_n, pr.xi_prev), pr.F_ext, pr.T_ext)
        # a new factorisation: the Newton Jacobian at the first iterate if the last one was
        newton_first = (KEEP_NEWTON_OPERATOR and self.factors.a0 != a0
                        and self.factors.newton_operator and not self.op.linear)
        if not newton_first:
            self.factors.operator(a0)
        mesh = _IterateMesh(self, pr.geometry, a0, hist_u)
        mesh.follow(pr.xi_n if xi_guess is None else xi_guess)
        x_D = self.imposed_values(self.x_dirichlet(pr.t_new), self.xi_imposed)
        z = self.first_iterate(pr.u_n if pr.u_guess is None else pr.u_guess, pr.p_guess,
                                pr.xi_n if xi_guess is None else xi_guess)
        if newton_first:
            self.factorize_jacobian(self.E @ z + x_D, a0)  # booked as assembly, factorisation
        it = self._iterate(z, x_D, rigid_rhs, mesh, pr)
        t0 = time.perf_counter()
        mesh.follow(self.rigid(z))
        G, Rf, x = self.residual(z, x_D, mesh.rhs_u, rigid_rhs, mesh.A_uu)
        F, T = self.fluid_forces(Rf)
        self.timings["forces"] += time.perf_counter() - t0
        self._last = (mesh.rhs_u, x, mesh.A_uu)
        return StepSolution(x=x, xi=self.rigid(z), force=F, torque=T, iterations=it)

    def _iterate(self, z, x_D, rigid_rhs, mesh: _IterateMesh, pr: StepProblem) -> int:
        """The chord iteration of one step from the first iterate ``z`` (updated in place);
        returns the iterations. A stall refreshes the operator with the Newton Jacobian."""
        a0 = pr.bdf2.a0
        scale = pr.velocity_scale()
        t0 = time.perf_counter()
        # the chord loop corrects each linear solve's error itself (exact residuals), so
        # it skips iterative refinement; a linear (Stokes) step needs the refined solve
        solve = self.solver.solve_correction if not self.op.linear else self.solver.solve
        stall = ChordStall(self.max_iterations, self.factors)
        refresh_time = 0.0  # seconds of the refreshes (booked as assembly, factorisation)
        evaluations = 0

        def stop(it, dz, z):
            if self.op.linear and pr.geometry is None:
                return True
            dn = float(np.abs(dz[: self.nu_z]).max())
            if not np.isfinite(dn):
                raise ConvergenceError(f"coupled step dt={pr.dt:.3e}: corrector produced NaN")
            tol = self.newton_tol * max(scale, float(np.abs(z[: self.nu_z]).max()))
            done = chord_converged(dn, 0.0 if stall.prev is None else stall.prev, it, tol)
            stall.observe(it, dn, done, tol)
            return done

        def correct(z, G, it):
            nonlocal refresh_time
            if stall.refresh_due(it):
                t_refresh = time.perf_counter()
                self.factorize_jacobian(self.E @ z + x_D, a0)  # booked as assembly, factorisation
                refresh_time += time.perf_counter() - t_refresh
            return -solve(G)

        def residual(z):
            nonlocal evaluations
            if evaluations > 0:
                mesh.follow(self.rigid(z))
            evaluations += 1
            return self.residual(z, x_D, mesh.rhs_u, rigid_rhs, mesh.A_uu)[0]

        it = newton_iterate(z, residual, correct, stop, max_iterations=self.max_iterations)
        if it is None:
            raise ConvergenceError(f"coupled step at t={pr.t_new:.6g} (dt={pr.dt:.3e}): corrector "
                                   f"did not converge in {self.max_iterations} iterations")
        self.timings["solve"] += time.perf_counter() - t0 - refresh_time
        return it


class _IterateMesh:
    """The mesh a corrector iterate is on (moving mesh: where the iterate puts the particles)
    with the velocity block and the history's right-hand side there."""

    def __init__(self, coupling: MonolithicCoupling, geometry, a0: float, hist_u):
        self.coupling, self.geometry, self.a0, self.hist_u = coupling, geometry, a0, hist_u
        self.A_uu = None  # None: the factorised operator's (the mesh has not moved)
        self.rhs_u = -coupling.fluid.density * (coupling.space.M @ hist_u)

    def follow(self, xi) -> None:
        """Move the coupling's mesh to where rigid velocities ``xi`` put the particles."""
        if self.geometry is None:
            return
        g = self.geometry(xi)
        if g is None:
            return
        c = self.coupling
        c.move(*g)
        self.A_uu = c.op.velocity_block(self.a0)
        self.rhs_u = -c.fluid.density * (c.space.M @ self.hist_u)
