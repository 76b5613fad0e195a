"""The coupled stepper: one object that owns and advances fluid, particles and mesh.

:class:`CoupledStepper` holds the DEM system, the mesh (with its recipe), the
coupling built on it and the :class:`~skfem_granular.coupled.state.CoupledState`
of the BDF2 histories, and advances them together. :meth:`CoupledStepper.evolve`
is a generator yielding ``(t, report)`` after every accepted step, in the style
of :func:`skfem_granular.fluid.evolve`, so a notebook can own the loop;
:class:`~skfem_granular.simulation.Simulation` drives the same generator and
records history, frames and checkpoints from what it yields.

Who owns what. The DEM system is the one owner of the particles' state at the
current time: poses, velocities, contact springs. A step reads it, solves, and
writes the accepted result back once (:meth:`DEMSystem.set_motion`); nothing
else keeps a copy of it. The stepper's ``state`` owns the fluid state and the
earlier particle states the BDF2 formulas need (``xi_prev``, ``q_prev``).

One step (monolithic coupling, the default):

1. remesh first if a particle has moved ``remesh_fraction`` of its outline edge
   since the mesh was built (or, on the default graded mesh, when a particle's Reynolds
   number first exceeds :data:`~skfem_granular.coupled.wake.WAKE_REYNOLDS`:
   :mod:`~skfem_granular.coupled.wake`), transferring ``u_n``, ``u_{n-1}`` and the BDF2
   derivatives (:mod:`skfem_granular.coupled.transfer`); a core closer to a wall or
   another core than the mesh follows is remeshed once, then stops the run with the fix
   (:mod:`skfem_granular.coupled.landing`);
2. external forces: buoyancy-reduced gravity ``(m - rho_f A_core) g``; with
   contacts, the DEM subcycles over the step with the last fluid force held and
   gives the positions and the mean contact force (from the momentum change, so
   the impulse of a short contact counts in full);
3. the coupled BDF2 corrector of fluid and rigid velocities (the paper's Eq. 1,
   :mod:`skfem_granular.coupled.monolithic`), positions by the same BDF2 formula
   when there are no contacts;
4. acceptance (:func:`skfem_granular.timestep.accept_step`): a step whose
   corrector fails is halved (at most :data:`MAX_RETRIES` times, the DEM
   restored first); the following steps grow back by at most 2x per step
   (variable-step BDF2 is zero-stable below 1 + sqrt(2)).

Particles with a prescribed motion (:class:`~skfem_granular.dem.PrescribedMotion`)
are at their motion's pose at the end of every step; their rigid velocities are
the BDF2 derivative of those poses (so the pose the BDF2 formula gives back from
them, e.g. for the moving mesh, is the prescribed one), handed to the coupling as
known Dirichlet data (``xi_imposed``) instead of being solved for; the force on
them is the coupling's consistent reaction force, reported as for free particles.

Adaptive steps (``time.adaptive``) follow the local error as
:func:`~skfem_granular.fluid.evolve` does: an AB2 predictor of the fluid
velocities and the rigid velocities, Milne's device on the predictor-corrector
difference, :class:`~skfem_granular.timestep.StepController` accepting or
rejecting and proposing the next step (at most ``time.dt``). The error is
relative to the largest velocity (fluid, particle, or ``omega`` times the
particle's radius), at least :data:`VELOCITY_FLOOR`. The first four steps on a
new mesh keep their size without an estimate: interpolation onto a new mesh is
not exactly divergence-free and the particle surfaces have moved, so the first
step there projects the fluid, and through the added mass the particles, by an
amount that does not shrink with the step (measured: 20 % of the largest fluid
velocity and 0.15 % of the particle's, for a particle at Re 100 remeshed every
6.5 um), and the BDF2 derivatives carry that jump for three more steps.

Steps with a contact force, and the :data:`EULER_AFTER_CONTACT` steps after
the last one, are backward-Euler steps. A contact is an impulse far shorter
than the step; BDF2 answers such a kick with an overshoot (it is A- and
G-stable, but its kinetic energy is not monotone): with BDF2 throughout a
hexagon hitting the floor at 3 cm/s in water came back with 1.37, 1.16, 0.98
times the kinetic energy of grain + fluid at fixed steps of 20, 10, 5 us, and
a grain resting on the floor rattled at 8e-5 m/s. Backward Euler is monotone:
0.68, 0.74, 0.76 at 20, 10, 5 us (0.76 adaptive), the resting grain still to
5e-12 m/s. The fluid is first-order accurate in time during contacts
(:attr:`CoupledStepper.euler_steps` counts those steps).
"""

from __future__ import annotations

import time
from typing import Any, cast

import numpy as np

from .. import timestep as ts
from ..dem.motion import pose_derivative
from ..fluid.errors import ConvergenceError
from .ale_rules import ALE_SLIDE_WALLS, REMESH_REASONS, remesh_reason, step_geometry
from .build import build_coupling, outline_areas, outline_edge
from .landing import landing_check
from .mesh_motion import MeshMotion, mesh_quality
from .state import CoupledState, StepReport
from .transfer import lag, transfer_histories
from .wake import WakeGrading

#: Halvings of a step before the run gives up.
MAX_RETRIES = 4

#: Rejections of one step by the error control before the run gives up.
MAX_REJECTIONS = 10

#: Velocities below this (m/s) count as this in the relative local error.
VELOCITY_FLOOR = 1e-6

#: Backward-Euler steps after the last step with a contact force (module notes).
EULER_AFTER_CONTACT = 2

#: A new mesh's first factorisation is of the Newton Jacobian (when the mesh it replaces
#: held one) if that mesh lived at most this many steps: where the flow outpaces the
#: meshes, the linear operator would stall on the first step and be refreshed at once;
#: on meshes that live longer a Jacobian of the first iterate goes stale within a few
#: steps and is refreshed anyway (measured: benchmarks page).
NEWTON_CARRY_STEPS = 4


class SimulationError(RuntimeError):
    """A run stopped early; the history and the last good state were written."""


class CoupledStepper:
    """Fluid, rigid particles and their mesh, advanced together one BDF2 step at a time.

    Parameters
    ----------
    scene : Scene
        With fluid (a dry scene has no coupled stepper).
    dem : DEMSystem
        The particles; the stepper advances it and is its only writer while it runs.
    mesh : meshing.BodyFittedMesh or skfem.MeshTri
        The fluid mesh around the particle cores; a bare ``MeshTri`` (no recipe)
        cannot be remeshed.
    contacts_active : bool
        Whether the DEM's contact forces enter the steps.
    timings : dict, optional
        Wall times per phase are added to it (default: a new dict).
    centers, angles : ndarray, optional
        The particles' poses the mesh was built for (default: the DEM's now).
    terms : UserTerms, optional
        User forms added to the fluid equations on every mesh
        (:class:`~skfem_granular.fluid.UserTerms`).
    assembly : {"compiled", "scikit-fem"}
        How the fluid's built-in blocks are assembled on every mesh
        (:class:`~skfem_granular.fluid.TaylorHood`).

    Attributes
    ----------
    state : CoupledState
        The BDF2 histories at the current time.
    remeshes, retries, rejections, euler_steps : int
        Counts of remeshes, step halvings, rejected steps and backward-Euler
        steps taken because of contacts.
    remesh_energy_ratios : list of float
        Fluid kinetic energy after / before each transfer onto a new mesh.
    worst_mesh : dict
        The poorest mesh the steps of this stepper ended on: ``min_angle`` (degrees),
        ``min_area_ratio`` (a triangle's signed area over its area as built; <= 0 would
        be inverted) and the ``steps`` checked. A stepper rebuilt from a checkpoint
        starts it afresh: it covers the steps since then.
    """

    def __init__(self, scene, dem, mesh, *, contacts_active: bool, timings=None,
                 centers=None, angles=None, terms=None, assembly="compiled"):
        self.scene = scene
        self.terms, self.assembly = terms, assembly
        self.dem = dem
        self.contacts_active = bool(contacts_active)
        self.timings = {} if timings is None else timings
        for k in ("meshing", "assembly", "remeshing", "dem"):
            self.timings.setdefault(k, 0.0)
        self.g = np.asarray(scene.gravity) if scene.effects.gravity else np.zeros(2)
        # body-frame outlines: the same numbers whatever the particles' current pose
        # (a resumed run must see bit-identical buoyancy)
        p = dem.particles
        cores = [p.core_local[k, : p.core_count[k]].T for k in range(dem.n)]
        self.core_area = outline_areas(cores)
        self.edge = np.array([outline_edge(c, scene.mesh.delta_l) for c in cores])
        self.radius = np.array(
            [np.linalg.norm(c - c.mean(axis=1, keepdims=True), axis=0).max() for c in cores])
        self.remeshes = self.retries = self.rejections = self.euler_steps = 0
        self._factor_counts = {"factorizations": 0, "jacobian_refreshes": 0}
        self.remesh_energy_ratios: list[float] = []
        self.worst_mesh = {"min_angle": float("inf"), "min_area_ratio": float("inf"),
                           "steps": 0}
        #: moving mesh: why it was remeshed, ``{reason: count}`` (:func:`~.ale_rules.remesh_reason`)
        #: and ``wake``: the first remesh after :attr:`wake_grading` found a wake
        self.remesh_reasons = dict.fromkeys((*REMESH_REASONS, "wake"), 0)
        self._landing_remeshed = False  # a gap below LANDING_GAP has been remeshed for
        #: a :class:`~.flow_size.FlowSizing` grades every remesh by the flow too (field
        #: meshes); None (default): by the grains alone
        self.flow_sizing = None
        #: a :class:`~.wake.WakeGrading` refines every remesh of a default-graded mesh while
        #: a particle's Reynolds number is above its threshold (``[mesh] wake``, on by
        #: default for ``graded`` meshes with the default sigma); None: never
        self.wake_grading = (WakeGrading() if scene.mesh.wake and scene.mesh.sigma is None
                             and scene.mesh.kind in ("auto", "graded") else None)
        self._set_mesh(mesh, centers, angles)
        self.state = CoupledState(u_n=np.zeros(self.space.nu), p_n=None,
                                  x=np.zeros(self.space.N), F_held=np.zeros((2, dem.n)),
                                  T_held=np.zeros(dem.n),
                                  nodes_n=self.mesh.p if self.ale else None)

    # ------------------------------------------------------------------ mesh
    @property
    def mesh(self):
        """The fluid mesh in use (``skfem.MeshTri``; moved with the particles under ALE)."""
        return self.coupling.space.mesh

    @property
    def space(self):
        """The Taylor-Hood discretisation of :attr:`mesh`."""
        return self.coupling.space

    @property
    def factor_counts(self) -> dict:
        """Factorisations of the run so far: ``factorizations`` of the BDF2-Stokes operator
        (a new step size or step kind, a new mesh) and ``jacobian_refreshes`` (a Newton
        Jacobian where the chord iteration stalled), over every mesh."""
        f = getattr(getattr(self, "coupling", None), "factors", None)
        c = dict(self._factor_counts)
        if f is not None:
            c["factorizations"] += f.factorizations
            c["jacobian_refreshes"] += f.refreshes
        return c

    @property
    def ale(self) -> bool:
        """Whether the mesh moves with the particles (:attr:`Scene.moving_mesh`)."""
        return self.scene.moving_mesh

    def __repr__(self) -> str:
        return (f"CoupledStepper({self.scene.coupling}, {'ALE' if self.ale else 'fixed'} mesh, "
                f"t={self.state.t:.6g} s, {self.dem.n} particles, {self.space.N} unknowns, "
                f"{self.remeshes} remeshes)")

    def _set_mesh(self, mesh, centers=None, angles=None):
        old = getattr(self, "coupling", None)
        if old is not None:  # keep the phase times and counts of the coupling being replaced
            for k, v in old.timings.items():
                self.timings[k] = self.timings.get(k, 0.0) + v
            self._factor_counts = self.factor_counts
        t0 = time.perf_counter()
        self.meshed = mesh
        dem = self.dem
        built = getattr(mesh, "mesh", mesh)
        self.coupling = build_coupling(self.scene, built, dem, centers=centers,
                                       terms=self.terms, assembly=self.assembly)
        if old is not None and self.state.since_remesh <= NEWTON_CARRY_STEPS:
            # a short-lived mesh's Newton Jacobian: the new mesh starts on one too
            self.coupling.factors.newton_operator = old.factors.newton_operator
        self.reference_space = self.coupling.space
        self.mesh_centers = dem.positions.copy() if centers is None else np.array(centers)
        self.mesh_angles = dem.angles.copy() if angles is None else np.array(angles)
        self.motion = None
        if self.ale:
            nodes = [np.unique(built.facets[:, built.boundaries[f"particle{k}"]])
                     for k in range(dem.n)]
            poses = np.vstack([self.mesh_centers, self.mesh_angles[None, :]])
            self.motion = MeshMotion(built, nodes, poses, slide_walls=ALE_SLIDE_WALLS)
        else:  # a fixed mesh's smallest angle, once (:meth:`_note_mesh_quality`)
            import meshing

            self._built_angle = float(meshing.mesh_stats(built).min_angle)
        self.timings["assembly"] += time.perf_counter() - t0

    def _remesh_if_moved(self, force: bool = False):
        """Remesh when a particle has moved too far (or ``force``); transfers the fluid
        histories."""
        import meshing

        dem, sc, s = self.dem, self.scene, self.state
        moved = lag(self.mesh_centers, self.mesh_angles, dem.positions, dem.angles, self.radius)
        wake = self._wake_options()
        if force:
            pass
        elif wake.get("sigma") is not None and wake["sigma"] != self.meshed.recipe.options.get(
                "sigma"):  # a wake starts: its circles now, not at the next remesh
            self.remesh_reasons["wake"] += 1
        elif self.ale:
            dt_ratio = (None if s.dt_prev is None or s.xi_prev is None
                        else sc.time.dt / s.dt_prev)
            reason = remesh_reason(self.motion, s.nodes_n, moved, dem.particles.q, s.q_prev,
                                   dt_ratio, self.radius, self.edge, sc.remesh_travel)
            if reason is None:
                return
            self.remesh_reasons[reason] += 1
        elif not np.any(moved > sc.remesh_fraction * self.edge):
            return
        if not sc.effects.remeshing:
            raise RuntimeError(
                f"particles moved {moved.max():.3g} m, more than "
                f"remesh_fraction x edge length, and effects.remeshing is off")
        if getattr(self.meshed, "recipe", None) is None:
            raise RuntimeError(
                f"particles moved {moved.max():.3g} m, more than remesh_fraction x edge "
                "length, and the mesh given to the simulation has no recipe to remesh it "
                "(pass a meshing.BodyFittedMesh from meshing.build)")
        t0 = time.perf_counter()
        old = self.space
        # moving mesh: the t_{n-1} fields sit at the nodes' t_{n-1} positions
        old_prev = (self.reference_space.moved(s.nodes_prev)
                    if self.ale and s.nodes_prev is not None and s.q_prev is not None
                    else None)
        changes: dict[str, Any] = {}
        if self.flow_sizing is not None:
            if self.meshed.recipe.kind != "field":
                raise ValueError(f"flow_sizing: needs a 'field' mesh ([mesh] kind = "
                                 f"\"field\"), the mesh is {self.meshed.recipe.kind!r}")
            changes["size"] = self.flow_sizing(self.space, s.u_n)
        new_mesh = meshing.remesh(self.meshed, dem.core_outlines(), **changes, **wake)
        self.timings["meshing"] += time.perf_counter() - t0
        self._set_mesh(new_mesh)
        t0 = time.perf_counter()
        e_old = 0.5 * sc.fluid.density * float(s.u_n @ (old.M @ s.u_n))
        new_prev = None
        if self.ale:
            s.nodes_n, s.nodes_prev = self.mesh.p, None  # built where the particles are
            if old_prev is not None:
                # the new mesh's own t_{n-1} configuration: its outlines where the particles
                # were then, so the mesh velocity stays the particles' velocity at the
                # outlines and the t_{n-1} history is the field at those points then
                s.nodes_prev = self.motion.positions(s.q_prev)
                new_prev = self.reference_space.moved(s.nodes_prev)
        # projected divergence-free on the moving mesh only: on the fixed mesh the particle
        # boundary jumps at a remesh, and projecting there changed a colliding pair's
        # momentum (measured: 8e-2 of a grain's against 2e-4)
        transfer_histories(s, old, self.space, old_prev=old_prev, new_prev=new_prev,
                           project=self.coupling.op if self.ale else None)
        s.since_remesh = 0
        # interpolation must not create kinetic energy out of nothing: record the ratio
        if e_old > 0:
            self.remesh_energy_ratios.append(self.fluid_energy() / e_old)
        self.timings["remeshing"] += time.perf_counter() - t0
        self.remeshes += 1

    def _wake_options(self) -> dict:
        """The builder options :attr:`wake_grading` asks of the next remesh (``{}``: none,
        for a mesh that is not a remeshable ``graded`` one, with remeshing off, or
        without the rule)."""
        recipe = getattr(self.meshed, "recipe", None)
        if (self.wake_grading is None or recipe is None or recipe.kind != "graded"
                or not self.scene.effects.remeshing):
            return {}
        return self.wake_grading.changes(self.dem.velocities, self.radius,
                                         self.scene.fluid.kinematic_viscosity)

    def _check_landing(self):
        """Stop with one line and the fix when a core is closer to a wall or another core
        than the mesh follows (:mod:`~skfem_granular.coupled.landing`), after one remesh."""
        msg = landing_check(self.dem, self.scene.domain, self.edge, self.contacts_active,
                            self.state.t)
        if msg is None:
            self._landing_remeshed = False
        elif (self._landing_remeshed or not self.scene.effects.remeshing
              or getattr(self.meshed, "recipe", None) is None):
            raise SimulationError(msg)
        else:
            self._landing_remeshed = True
            self._remesh_if_moved(force=True)

    # ------------------------------------------------------------------ physics
    def weight(self) -> np.ndarray:
        """Buoyancy-reduced gravity ``(m - rho_f A_core) g`` of the particles, ``(2, K)``.

        Buoyancy is that of the core, the outline the fluid sees (the hydrostatic
        pressure is left out of the solved pressure, see the design notes)."""
        rho_f = self.scene.fluid.density
        return np.outer(self.g, self.dem.mass) - rho_f * np.outer(self.g, self.core_area)

    def callback_forces(self, t: float):
        """The DEM's ``force_callbacks`` ``f(dem, t) -> (F (2, K), T (K,))``, summed.

        A coupled step evaluates them once, at its end time ``t`` with the particles where
        the step starts, and holds them over the step as it holds the other external
        forces (the DEM's substeps through contacts see the same held value)."""
        dem = self.dem
        F, T = np.zeros((2, dem.n)), np.zeros(dem.n)
        for i, f in enumerate(dem.force_callbacks):
            try:
                Fc, Tc = f(dem, t)
                F = F + np.broadcast_to(np.asarray(Fc, dtype=float), (2, dem.n))
                T = T + np.broadcast_to(np.asarray(Tc, dtype=float), (dem.n,))
            except (TypeError, ValueError) as exc:
                raise ValueError(f"force_callbacks[{i}]: must return (F, T) of shapes (2, "
                                 f"{dem.n}) and ({dem.n},) (or broadcastable): {exc}") from None
        return F, T

    def _dem_predictor(self, dt, F_held, T_held):
        """Subcycle the DEM over ``dt`` with the fluid force and the callbacks' held.

        ``F_held``, ``T_held``: the fluid force of the last step plus the callbacks'
        (:meth:`callback_forces`; the DEM does not evaluate its callbacks again here).
        Returns the mean contact force ``(2, K)`` and torque ``(K,)`` over the step
        (from the momentum change, so impulses of short contacts count in full) and
        the poses ``(3, K)`` at the end of the step.
        """
        dem = self.dem
        buoyancy = self.scene.fluid.density * np.outer(self.g, self.core_area)
        dem.external_force[...] = F_held - buoyancy
        dem.external_torque[...] = T_held
        v0 = dem.velocities.copy()
        w0 = dem.angular_velocities.copy()
        callbacks, dem.force_callbacks = dem.force_callbacks, []
        try:
            dem.advance(dt)
        finally:
            dem.force_callbacks = callbacks
        F_c = (dem.mass * (dem.velocities - v0) / dt - np.outer(self.g, dem.mass)
               - dem.external_force)
        T_c = dem.inertia * (dem.angular_velocities - w0) / dt - dem.external_torque
        if dem.imposed.any():  # moved by their motion, not by forces: no contact force
            F_c[:, dem.imposed] = 0.0
            T_c[dem.imposed] = 0.0
        return F_c, T_c, dem.particles.q.copy()

    def _contact_force_acted(self, xi_n, step, F_ext, F_c, T_c) -> bool:
        """Whether the DEM predictor's mean contact force is more than the round-off of the
        momentum difference it comes from (or a contact is open at the end of the step)."""
        dem = self.dem
        if dem.contact_count().max() > 0:
            return True
        eps = 1e3 * np.finfo(float).eps
        v = np.abs(np.concatenate([xi_n[:2], dem.velocities], axis=1)).max()
        F_held = self.state.F_held
        assert F_held is not None  # a stepper's state always holds the last fluid force
        noise = eps * (dem.mass.max() * v / step + np.abs(F_ext).max() + np.abs(F_held).max())
        return bool(np.abs(F_c).max() > noise or np.abs(T_c / self.radius).max() > noise)

    def _attempt(self, step: float):
        """One coupled BDF2 step of size ``step`` from the current state, not committed.

        Returns ``(new state, solver result, accelerations (3, K), poses (3, K),
        rigid velocities (3, K))``. Steps with a contact force, and the
        :data:`EULER_AFTER_CONTACT` steps after the last one, are backward-Euler steps.
        """
        s, dem = self.state, self.dem
        q_n, xi_n = dem.particles.q.copy(), dem.particles.v.copy()
        F_cb, T_cb = self.callback_forces(s.t + step)
        F_ext, T_ext = self.weight() + F_cb, T_cb
        t0 = time.perf_counter()
        touching = False
        q_dem = None  # the DEM's poses at the end of the step, when it was advanced
        # no contact can start within this step: the DEM's substeps would only integrate
        # the rigid-body motion that the coupled step integrates itself
        if self.contacts_active and self.dem.contact_possible(step, float(np.hypot(*self.g))):
            F_c, T_c, q_dem = self._dem_predictor(step, s.F_held + F_cb, s.T_held + T_cb)
            touching = self._contact_force_acted(xi_n, step, F_ext, F_c, T_c)
            F_ext, T_ext = F_ext + F_c, T_ext + T_c
        self.timings["dem"] += time.perf_counter() - t0
        euler = s.dt_prev is None or touching or s.contact_age < EULER_AFTER_CONTACT
        dt_prev = None if euler else s.dt_prev
        u_prev = None if euler else s.u_prev
        xi_prev = None if euler else s.xi_prev
        # linear extrapolation of the last two states as the Newton initial guess (through
        # contacts the DEM's end-of-substep velocities were tried instead: a 10-50x smaller
        # first update, the same number of iterations)
        w = 0.0 if s.dt_prev is None else step / s.dt_prev
        u_guess = s.u_n if s.u_prev is None else s.u_n + w * (s.u_n - s.u_prev)
        xi_guess = xi_n if s.xi_prev is None else xi_n + w * (xi_n - s.xi_prev)
        a0, a1, a2 = ts.bdf2_coefficients(step, dt_prev)
        geometry = None
        if self.ale:
            geometry = step_geometry(self.motion, self.reference_space, s.nodes_n, s.nodes_prev,
                                     (a0, a1, a2), q_n,
                                     s.q_prev if dt_prev is not None else None, q_dem,
                                     self.radius, self.edge, s.t)
        moving: dict[str, Any] = {} if geometry is None else {"geometry": geometry}
        imposed = dem.imposed if dem.imposed.any() else None
        if imposed is not None:
            # prescribed motions: the poses at t_{n+1} are the motions'; the velocities their
            # BDF2 derivative (so the pose the BDF2 formula gives back, e.g. the mesh's, is it)
            q_imp = dem.prescribed_poses(s.t + step)
            moving["xi_imposed"] = pose_derivative(q_imp, q_n, s.q_prev, step, dt_prev)
        res = self.coupling.step(step, dt_prev, s.u_n, u_prev, xi_n, xi_prev, F_ext, T_ext,
                                 s.t + step, p_guess=s.p_n, u_guess=u_guess, xi_guess=xi_guess,
                                 **moving)
        xi_new = res["xi"]
        if q_dem is not None:
            q_new = q_dem
        else:
            q_prev = cast(np.ndarray, s.q_prev)  # held whenever dt_prev is
            q_new = (xi_new - a1 * q_n - (a2 * q_prev if dt_prev is not None else 0.0)) / a0
        if imposed is not None:  # exactly on the trajectory
            q_new = q_new.copy()
            q_new[:, imposed] = q_imp[:, imposed]
        x = res["x"]
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(q_new))):
            raise ConvergenceError(f"step at t={s.t + step:.6g}: the solution contains NaN/inf")
        acc = a0 * xi_new + a1 * xi_n + (a2 * xi_prev if xi_prev is not None else 0.0)
        nu = self.space.nu
        u_new = x[:nu].copy()
        du = None
        if self.scene.time.adaptive:
            du = a0 * u_new + a1 * s.u_n + (a2 * u_prev if u_prev is not None else 0.0)
        new = CoupledState(u_n=u_new, p_n=x[nu:].copy(), x=x, t=s.t + step, u_prev=s.u_n,
                           xi_prev=xi_n, q_prev=q_n, dt_prev=step, F_held=res["force"],
                           T_held=res["torque"], du_n=du, du_prev=s.du_n, dxi_n=acc,
                           dxi_prev=s.dxi_n, since_remesh=s.since_remesh + 1,
                           contact_age=0 if touching else s.contact_age + 1, euler=euler)
        if self.ale:
            new.nodes_n, new.nodes_prev = self.coupling.space.mesh.p, s.nodes_n
        return new, res, acc, q_new, xi_new

    def local_error(self, attempt, step: float) -> float | None:
        """Milne estimate of the local error of an attempted step, relative; None if unknown.

        A BDF2 step is compared with the AB2 predictor, a backward-Euler step (contacts)
        with the forward-Euler one (Milne factor 1/2). Needs the derivative at the start.
        """
        s = self.state
        new, _, _, _, xi_new = attempt
        if s.dt_prev is None or s.du_n is None or s.dxi_n is None or s.since_remesh < 4:
            return None
        dt_prev = None if new.euler else s.dt_prev
        c = ts.milne_factor(step, dt_prev)
        u_pred = ts.predict(s.u_n, s.du_n, s.du_prev, step, dt_prev)
        xi_pred = ts.predict(new.xi_prev, s.dxi_n, s.dxi_prev, step, dt_prev)
        lever = np.vstack([np.ones((2, self.radius.size)), self.radius])  # omega as omega r
        e_u = c * np.abs(new.u_n - u_pred).max()
        e_xi = c * np.abs(lever * (xi_new - xi_pred)).max()
        scale = max(float(np.abs(new.u_n).max()), float(np.abs(lever * xi_new).max()),
                    VELOCITY_FLOOR)
        return float(max(e_u, e_xi) / scale)

    # ------------------------------------------------------------------ time loop
    def evolve(self, t_end: float | None = None):
        """Advance to ``t_end`` (default ``scene.time.t_end``); yields ``(t, StepReport)``.

        The generator yields after every accepted step, with the DEM, the mesh and
        :attr:`state` at that step; before the next step it remeshes if needed. The
        last step lands on ``t_end`` as :func:`~skfem_granular.fluid.evolve`'s does
        (:func:`~skfem_granular.timestep.step_toward`) and is reported at ``t_end``
        exactly; ``state.t`` stays the sum of the steps.

        Raises
        ------
        SimulationError
            When a step does not converge after :data:`MAX_RETRIES` halvings, or the
            error control rejects it more than :data:`MAX_REJECTIONS` times.
        """
        sc = self.scene
        t_end = sc.time.t_end if t_end is None else float(t_end)
        dt = sc.time.dt
        ctrl = None
        if sc.time.adaptive:
            ctrl = ts.StepController(tol=sc.time.tol, dt_min=sc.time.dt_min, dt_max=dt)
        s = self.state
        step_target = dt if s.dt_prev is None else min(dt, 2.0 * s.dt_prev)
        if ctrl is not None and s.dt_next is not None:
            step_target = s.dt_next
        while not ts.reached(self.state.t, t_end, dt):
            self._remesh_if_moved()
            self._check_landing()
            s = self.state
            step = min(step_target, dt)
            if s.dt_prev is not None:
                step = min(step, 2.0 * s.dt_prev)
            # land on t_end; keep the step (and the factorisation) if only rounding differs
            step = ts.step_toward(s.t, step, t_end, dt)
            new, res, acc, step = self._accepted(step, ctrl)
            self._note_mesh_quality()
            step_target = min(dt, 2.0 * step) if ctrl is None else new.dt_next
            # the last step reports t_end exactly; the clock (state.t) stays the sum of the
            # steps, which a run resumed past t_end goes on from (Simulation.resume)
            t = ts.end_time(new.t, t_end, dt)
            yield t, StepReport(t=t, dt=step, iterations=res["iterations"],
                                force=res["force"], torque=res["torque"], acceleration=acc,
                                error=new.error, fluid_energy=self.fluid_energy())

    def _note_mesh_quality(self):
        """Fold the mesh the step ended on into :attr:`worst_mesh`."""
        if self.ale:
            angle, ratio = mesh_quality(self.state.nodes_n, self.motion.t, self.motion.area_ref)
        else:  # a fixed mesh is as it was built: its smallest angle, measured once
            angle, ratio = self._built_angle, 1.0
        w = self.worst_mesh
        w["min_angle"] = min(w["min_angle"], angle)
        w["min_area_ratio"] = min(w["min_area_ratio"], ratio)
        w["steps"] += 1

    def _accepted(self, step: float, ctrl):
        """The accepted step from the current state; commits it (DEM and state)."""
        s = self.state
        saved = self.dem.save_state() if self.contacts_active else None
        undo = None if saved is None else (lambda: self.dem.restore_state(saved))
        try:
            out = ts.accept_step(self._attempt, step, failure=ConvergenceError,
                                 max_halvings=MAX_RETRIES, controller=ctrl,
                                 estimate=self.local_error, max_rejections=MAX_REJECTIONS,
                                 undo=undo)
        except ts.StepFailedError as exc:
            self.retries += exc.halvings
            self.rejections += exc.rejections
            if exc.reason == "halvings":
                raise SimulationError(
                    f"run stopped at t={s.t:.6g} s: {exc.__cause__} (after {MAX_RETRIES} step "
                    f"halvings down to dt={exc.step:.3g} s)") from exc.__cause__
            raise SimulationError(
                f"run stopped at t={s.t:.6g} s: local error {exc.error:.3g} > time.tol = "
                f"{ctrl.tol:g} after {exc.rejections} rejections down to dt={exc.step:.3g} s "
                f"(time.dt_min = {ctrl.dt_min:g})") from None
        self.retries += out.halvings
        self.rejections += out.rejections
        new, res, acc, q_new, xi_new = cast(tuple, out.result)
        if ctrl is not None:
            new.error = float("nan") if out.error is None else out.error
            new.dt_next = out.proposal
        if new.euler and s.dt_prev is not None:
            self.euler_steps += 1
        # t is the sum of the steps, not snapped to t_end (a run resumed past its t_end
        # goes on as the run that never stopped there); evolve reports t_end exactly
        self.dem.set_motion(q_new, xi_new, new.t)
        self.state = new
        return new, res, acc, out.step

    # ------------------------------------------------------------------ output
    def fluid_energy(self) -> float:
        """Kinetic energy ``rho u.M u / 2`` of the fluid now (J per unit depth)."""
        u = self.state.u_n
        return 0.5 * self.scene.fluid.density * float(u @ (self.space.M @ u))

    def flow(self):
        """The fluid now, as a :class:`~skfem_granular.fluid.Flow` on the current mesh."""
        return self.coupling.flow(self.state.x)

    def collect_timings(self) -> dict:
        """Add the coupling's phase times to :attr:`timings` (and zero them); returns it.

        The coupling's dict is zeroed in place: its factorisation cache books into the
        same dict (a new one would leave later factorisations out of every total)."""
        for k, v in self.coupling.timings.items():
            self.timings[k] = self.timings.get(k, 0.0) + v
            self.coupling.timings[k] = 0.0
        return self.timings

    # ------------------------------------------------------------------ checkpoints
    def checkpoint_state(self) -> dict:
        """Everything the next step depends on besides the scene and the DEM, as a dict.

        The stepper also forgets its factorisation and the DEM its neighbour list
        here, as a stepper rebuilt by :meth:`from_checkpoint_state` does: the run that
        wrote a checkpoint and any run resumed from it then do the same arithmetic
        from here on (bit for bit).
        """
        data = {"state": self.state, "mesh": self.meshed, "mesh_centers": self.mesh_centers,
                "flow_sizing": self.flow_sizing, "wake_grading": self.wake_grading,
                "mesh_angles": self.mesh_angles, "coupling_centers": self.coupling.centers.copy(),
                "counters": {"remeshes": self.remeshes, "retries": self.retries,
                             "rejections": self.rejections, "euler_steps": self.euler_steps,
                             **self.factor_counts,
                             "chord_extra_iterations": self.coupling.factors.extra_iterations,
                             **{"remesh_reasons." + k: v
                                for k, v in self.remesh_reasons.items()}}}
        self.dem.neighbours.invalidate()
        if self.ale:
            # a moved mesh's factorisation depends on where the mesh was when it was made:
            # keep it, and let a resumed stepper make the same one there
            # (the linear operator, or a Newton Jacobian at a recorded state: factor_x,
            # with the mesh velocity factor_w)
            on = getattr(self.coupling, "factorized_on", None)
            a0 = self.coupling.factors.a0
            if a0 is None or on is None:
                a0, on = None, (None, None, None, None)
            data.update(factor_a0=a0, factor_nodes=on[0], factor_centers=on[1],
                        factor_x=on[2], factor_w=on[3])
        else:
            data.update(factor_a0=None, factor_nodes=None, factor_centers=None,
                        factor_x=None, factor_w=None)
            self.coupling.forget_factorization()
        return data

    @classmethod
    def from_checkpoint_state(cls, scene, dem, data: dict, *, contacts_active: bool,
                              timings=None, terms=None) -> CoupledStepper:
        """The stepper that wrote ``data`` (:meth:`checkpoint_state`), for ``dem`` restored
        (``terms``: the user forms of the fluid, which a checkpoint does not hold)."""
        st = cls(scene, dem, data["mesh"], contacts_active=contacts_active, timings=timings,
                 centers=data["mesh_centers"], angles=data["mesh_angles"], terms=terms)
        st.state = data["state"]
        st.flow_sizing = data.get("flow_sizing")
        st.wake_grading = data.get("wake_grading", st.wake_grading)
        if st.ale and data.get("factor_a0") is not None:  # the writer's factorisation
            st.coupling.move(st.reference_space.moved(data["factor_nodes"]),
                             data["factor_centers"], data["factor_w"])
            if data["factor_x"] is None:
                st.coupling.factors.operator(data["factor_a0"])
            else:
                st.coupling.factorize_jacobian(data["factor_x"], data["factor_a0"])
        # what the writer's factorisation had cost beyond fresh ones (ChordStall's ledger)
        st.coupling.factors.extra_iterations = data["counters"].get("chord_extra_iterations", 0)
        if st.ale and st.state.nodes_n is not None:  # the mesh where the last step left it
            st.coupling.move(st.reference_space.moved(st.state.nodes_n),
                             data["coupling_centers"], None)
        c = data["counters"]
        st.remeshes, st.retries = c["remeshes"], c["retries"]
        st.rejections, st.euler_steps = c["rejections"], c["euler_steps"]
        st.remesh_reasons.update({k.split(".", 1)[1]: v for k, v in c.items()
                                  if k.startswith("remesh_reasons.")})
        # the counts so far, less what the rebuilt coupling has already done
        done = st.factor_counts
        st._factor_counts = {k: c[k] - done[k] + st._factor_counts[k] for k in done}
        return st
