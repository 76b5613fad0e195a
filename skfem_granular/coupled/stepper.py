"""The coupled stepper: the loop that advances fluid, particles and mesh together.

:class:`CoupledStepper` holds the DEM system, a :class:`~.mesh_keeper.MeshKeeper` (the
mesh, the coupling on it and the remesh rules) and the
:class:`~skfem_granular.coupled.state.CoupledState` of the BDF2 histories.
:meth:`CoupledStepper.evolve` is a generator yielding ``(t, report)`` after every
accepted step, in the style of :func:`skfem_granular.fluid.evolve`, so a notebook can own
the loop; :class:`~skfem_granular.simulation.Simulation` drives the same generator.

Who owns what. The DEM system is the one owner of the particles' state at the current
time: poses, velocities, contact springs. A step reads it, solves, and writes the
accepted result back once; the stepper's ``state`` owns the fluid state and the earlier
particle states the BDF2 formulas need.

One step:

1. remesh first if the keeper gives a reason (:meth:`MeshKeeper.reason`), and once when
   a core comes closer to a wall or another core than the mesh follows;
2. try the step (:func:`~.attempt.attempt_step`): held forces, through contacts the
   DEM's substeps, the coupled BDF2 corrector (the paper's Eq. 1);
3. accept it (:func:`skfem_granular.timestep.accept_step`): a step whose corrector fails
   is halved (at most :data:`MAX_RETRIES` times); with ``time.adaptive`` the Milne
   estimate (:func:`~.attempt.local_error`) accepts or rejects it and proposes the next
   step; steps grow back by at most 2x per step (variable-step BDF2 is zero-stable below
   1 + sqrt(2));
4. commit: the DEM takes the step's poses and velocities, the state the new histories.

Particles with a prescribed motion are at their motion's pose at the end of every step;
their rigid velocities are handed to the coupling as known Dirichlet data.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .. import timestep as ts
from ..fluid.errors import ConvergenceError
from .attempt import (  # noqa: F401 (re-exported: the step's constants)
    EULER_AFTER_CONTACT,
    VELOCITY_FLOOR,
    Attempt,
    StepParts,
    attempt_step,
    local_error,
)
from .build import CoreSizes
from .errors import SimulationError
from .forcing import Forcing
from .mesh_keeper import NEWTON_CARRY_STEPS, MeshKeeper, fluid_energy  # noqa: F401
from .state import CoupledState, StepReport

#: Halvings of a step before the run gives up.
MAX_RETRIES = 4

#: Rejections of one step by the error control before the run gives up.
MAX_REJECTIONS = 10

__all__ = ["MAX_REJECTIONS", "MAX_RETRIES", "CoupledStepper", "SimulationError"]


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
    poses : (3, K) ndarray, optional
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
    keeper : MeshKeeper
        The mesh, the coupling on it and the remesh rules (remesh counts and reasons,
        energy ratios, the poorest mesh the steps ended on).
    retries, rejections, euler_steps : int
        Counts of step halvings, rejected steps and backward-Euler steps taken because
        of contacts.
    """

    def __init__(self, scene, dem, mesh, *, contacts_active: bool, timings=None,
                 poses=None, terms=None, assembly="compiled"):
        self.scene, self.dem = scene, dem
        self.contacts_active = bool(contacts_active)
        self.timings = {} if timings is None else timings
        for k in ("meshing", "assembly", "remeshing", "dem"):
            self.timings.setdefault(k, 0.0)
        self.cores = CoreSizes.of(dem, scene.mesh.delta_l)
        self.forcing = Forcing(scene, dem, self.cores, self.timings)
        self.keeper = MeshKeeper(scene, dem, mesh, self.cores, self.timings, poses=poses,
                                 coupling_options={"terms": terms, "assembly": assembly})
        self.retries = self.rejections = self.euler_steps = 0
        self.state = CoupledState(u_n=np.zeros(self.space.nu), p_n=None,
                                  F_held=np.zeros((2, dem.n)),
                                  T_held=np.zeros(dem.n),
                                  nodes_n=self.mesh.p if self.ale else None)

    # ------------------------------------------------------------------ what it holds
    coupling = property(lambda self: self.keeper.coupling,
                        doc="The coupling on the mesh in use.")
    mesh = property(lambda self: self.keeper.mesh,
                    doc="The fluid mesh in use (moved with the particles under ALE).")
    space = property(lambda self: self.keeper.space,
                     doc="The Taylor-Hood discretisation of :attr:`mesh`.")
    meshed = property(lambda self: self.keeper.meshed,
                      doc="The mesh as built, with its recipe (``meshing.BodyFittedMesh``).")
    ale = property(lambda self: self.keeper.ale,
                   doc="Whether the mesh moves with the particles.")
    remeshes = property(lambda self: self.keeper.remeshes, doc="Remeshes so far.")
    remesh_reasons = property(lambda self: self.keeper.remesh_reasons,
                              doc="Why the moving mesh was remeshed, ``{reason: count}``.")
    mesh_repairs = property(lambda self: self.keeper.repairs,
                            doc="Repairs of the moving mesh by edge flips instead of a "
                                "remesh: ``done``, ``refused``, ``flipped`` (edges).")
    remesh_energy_ratios = property(
        lambda self: self.keeper.remesh_energy_ratios,
        doc="Fluid kinetic energy after / before each transfer onto a new mesh.")
    worst_mesh = property(
        lambda self: self.keeper.worst_mesh,
        doc="The poorest mesh the steps ended on: ``min_angle`` (degrees), "
            "``min_area_ratio`` (signed area over the area as built) and the ``steps`` "
            "checked (since this stepper was built).")
    factor_counts = property(lambda self: self.keeper.factor_counts,
                             doc="Factorisations over every mesh so far.")
    radius = property(lambda self: self.cores.radius, doc="The cores' bounding radii.")
    core_area = property(lambda self: self.cores.area, doc="The cores' areas.")

    @property
    def flow_sizing(self):
        """A :class:`~.flow_size.FlowSizing` grading every remesh by the flow too (field
        meshes); None: by the grains alone."""
        return self.keeper.flow_sizing

    @flow_sizing.setter
    def flow_sizing(self, value):
        self.keeper.flow_sizing = value

    @property
    def wake_grading(self):
        """A :class:`~.wake.WakeGrading` refining every remesh of a default-graded mesh
        while a particle's Reynolds number is above its threshold; None: never."""
        return self.keeper.wake_grading

    @wake_grading.setter
    def wake_grading(self, value):
        self.keeper.wake_grading = value

    def weight(self) -> np.ndarray:
        """Buoyancy-reduced gravity of the particles, ``(2, K)`` (:meth:`Forcing.weight`)."""
        return self.forcing.weight()

    def callback_forces(self, t: float):
        """The DEM's force callbacks at ``t``, summed (:meth:`Forcing.callbacks`)."""
        return self.forcing.callbacks(t)

    def __repr__(self) -> str:
        return (f"CoupledStepper({self.scene.coupling}, {'ALE' if self.ale else 'fixed'} mesh, "
                f"t={self.state.t:.6g} s, {self.dem.n} particles, {self.space.N} unknowns, "
                f"{self.remeshes} remeshes)")

    # ------------------------------------------------------------------ remeshing
    def remesh(self, reason: str = "forced") -> None:
        """Replace the mesh now (:meth:`MeshKeeper.replace`), the fluid histories moved."""
        self.state = self.keeper.replace(self.state, reason)

    def remesh_if_needed(self) -> str | None:
        """Repair or remesh if the keeper gives a reason (:meth:`MeshKeeper.reason`,
        :meth:`MeshKeeper.repair`), then remesh once more if a core landed
        (:meth:`MeshKeeper.landing`); returns the first reason or None."""
        reason = self.keeper.reason(self.state)
        if reason is not None:
            repaired = self.keeper.repair(self.state, reason)
            if repaired is None:
                self.remesh(reason)
            else:
                self.state = repaired
        self.state = self.keeper.landing(self.state, self.contacts_active)
        return reason

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
            self.remesh_if_needed()
            s = self.state
            step = min(step_target, dt)
            if s.dt_prev is not None:
                step = min(step, 2.0 * s.dt_prev)
            # land on t_end; keep the step (and the factorisation) if only rounding differs
            step = ts.step_toward(s.t, step, t_end, dt)
            taken, step = self._accepted(step, ctrl)
            self.keeper.note_quality(self.state)
            step_target = min(dt, 2.0 * step) if ctrl is None else self.state.dt_next
            # the last step reports t_end exactly; the clock (state.t) stays the sum of the
            # steps, which a run resumed past t_end goes on from (Simulation.resume)
            t = ts.end_time(self.state.t, t_end, dt)
            sol = taken.solution
            yield t, StepReport(t=t, dt=step, iterations=sol.iterations, force=sol.force,
                                torque=sol.torque, acceleration=taken.acceleration,
                                error=self.state.error, fluid_energy=self.fluid_energy())

    def _accepted(self, step: float, ctrl) -> tuple[Attempt, float]:
        """The accepted attempt from the current state and its step; commits it."""
        s = self.state
        parts = StepParts(self.dem, self.forcing, self.keeper, self.contacts_active,
                          self.scene.time.adaptive)
        try:
            out = ts.accept_step(lambda h: attempt_step(parts, s, h), step,
                                 failure=ConvergenceError, max_halvings=MAX_RETRIES,
                                 controller=ctrl, max_rejections=MAX_REJECTIONS,
                                 estimate=lambda a, h: local_error(s, a, h, self.cores.radius))
        except ts.StepFailedError as exc:
            self.retries += exc.halvings
            self.rejections += exc.rejections
            raise self._failure(exc, ctrl) from (exc.__cause__ if exc.reason == "halvings"
                                                 else None)
        self.retries += out.halvings
        self.rejections += out.rejections
        taken: Attempt = out.result  # type: ignore[assignment]
        new = taken.state
        if ctrl is not None:
            new = replace(new, error=float("nan") if out.error is None else out.error,
                          dt_next=out.proposal)
        if new.euler and s.dt_prev is not None:
            self.euler_steps += 1
        # t is the sum of the steps, not snapped to t_end (a run resumed past its t_end
        # goes on as the run that never stopped there); evolve reports t_end exactly
        if taken.dem_after is not None:
            self.dem.restore_snapshot(taken.dem_after)
        self.dem.set_motion(taken.poses, taken.solution.xi, new.t)
        self.state = new
        return taken, out.step

    def _failure(self, exc: ts.StepFailedError, ctrl) -> SimulationError:
        """The one-line error of a step that was not accepted."""
        t = self.state.t
        if exc.reason == "halvings":
            return SimulationError(
                f"run stopped at t={t:.6g} s: {exc.__cause__} (after {MAX_RETRIES} step "
                f"halvings down to dt={exc.step:.3g} s)")
        return SimulationError(
            f"run stopped at t={t:.6g} s: local error {exc.error:.3g} > time.tol = "
            f"{ctrl.tol:g} after {exc.rejections} rejections down to dt={exc.step:.3g} s "
            f"(time.dt_min = {ctrl.dt_min:g})")

    # ------------------------------------------------------------------ output
    def fluid_energy(self) -> float:
        """Kinetic energy ``rho u.M u / 2`` of the fluid now (J per unit depth)."""
        return fluid_energy(self.scene, self.space, self.state.u_n)

    def flow(self):
        """The fluid now, as a :class:`~skfem_granular.fluid.Flow` on the current mesh."""
        s = self.state
        p = np.zeros(self.space.N - self.space.nu) if s.p_n is None else s.p_n
        return self.coupling.flow(np.concatenate([s.u_n, p]))

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

        Call :meth:`forget_caches` with it when writing a checkpoint, so that the run that
        wrote it and any run resumed from it do the same arithmetic from there on.
        """
        k = self.keeper
        data = {"state": self.state, "mesh": k.meshed, "mesh_centers": k.mesh_poses[:2].copy(),
                "flow_sizing": k.flow_sizing, "wake_grading": k.wake_grading,
                "mesh_angles": k.mesh_poses[2].copy(), "travel_poses": k.travel_poses.copy(),
                "coupling_centers": self.coupling.centers.copy(),
                "counters": {"remeshes": k.remeshes, "retries": self.retries,
                             "rejections": self.rejections, "euler_steps": self.euler_steps,
                             **self.factor_counts,
                             "chord_extra_iterations": self.coupling.chord_extra_iterations,
                             **{"repairs." + r: v for r, v in k.repairs.items()},
                             **{"remesh_reasons." + r: v
                                for r, v in k.remesh_reasons.items()}}}
        # a moved mesh's factorisation depends on where the mesh was when it was made:
        # keep it, and let a resumed stepper make the same one there
        record = self.coupling.factor_record() if self.ale else {}
        data.update({f: record.get(f) for f in ("factor_a0", "factor_nodes",
                                                "factor_centers", "factor_x", "factor_w")})
        return data

    @staticmethod
    def with_later_entries(data: dict) -> dict:
        """``data`` (:meth:`checkpoint_state` of an earlier version) with the entries added
        since, at what that version did: a mesh graded where it was built (no repair)."""
        data = dict(data)
        if "travel_poses" not in data and "mesh_centers" in data:
            data["travel_poses"] = np.vstack([data["mesh_centers"],
                                              np.asarray(data["mesh_angles"])[None, :]])
        counters = data.get("counters")
        if isinstance(counters, dict) and "repairs.done" not in counters:
            data["counters"] = {**counters, "repairs.done": 0, "repairs.refused": 0,
                                "repairs.flipped": 0}
        return data

    def forget_caches(self) -> None:
        """Forget what a stepper rebuilt from a checkpoint would not hold: the DEM's
        neighbour list and, on a fixed mesh, the factorisation (a moving mesh's is remade
        where it was made, from :meth:`checkpoint_state`)."""
        self.dem.neighbours.invalidate()
        if not self.ale:
            self.coupling.forget_factorization()

    @classmethod
    def from_checkpoint_state(cls, scene, dem, data: dict, *, contacts_active: bool,
                              timings=None, terms=None) -> CoupledStepper:
        """The stepper that wrote ``data`` (:meth:`checkpoint_state`), for ``dem`` restored
        (``terms``: the user forms of the fluid, which a checkpoint does not hold)."""
        poses = np.vstack([data["mesh_centers"], np.asarray(data["mesh_angles"])[None, :]])
        st = cls(scene, dem, data["mesh"], contacts_active=contacts_active, timings=timings,
                 poses=poses, terms=terms)
        st.state = data["state"]
        k = st.keeper
        k.flow_sizing = data.get("flow_sizing")
        if data.get("travel_poses") is not None:  # a repaired mesh: where it was graded
            k.travel_poses = np.array(data["travel_poses"], dtype=float)
        k.wake_grading = data.get("wake_grading", k.wake_grading)
        if st.ale:  # the writer's factorisation
            st.coupling.refactor(data, k.reference_space)
        # what the writer's factorisation had cost beyond fresh ones (ChordStall's ledger)
        c = data["counters"]
        st.coupling.chord_extra_iterations = c.get("chord_extra_iterations", 0)
        if st.ale and st.state.nodes_n is not None:  # the mesh where the last step left it
            st.coupling.move(k.reference_space.moved(st.state.nodes_n),
                             data["coupling_centers"], None)
        k.remeshes, st.retries = c["remeshes"], c["retries"]
        st.rejections, st.euler_steps = c["rejections"], c["euler_steps"]
        k.remesh_reasons.update({r.split(".", 1)[1]: v for r, v in c.items()
                                 if r.startswith("remesh_reasons.")})
        k.repairs.update({r.split(".", 1)[1]: v for r, v in c.items()
                          if r.startswith("repairs.")})
        # the counts so far, less what the rebuilt coupling has already done
        done = st.factor_counts
        k.retired_factor_counts = {f: c[f] - done[f] + k.retired_factor_counts[f]
                                   for f in done}
        return st
