"""The fluid mesh of a coupled run: the mesh, the coupling on it, its motion and every remesh rule.

:class:`MeshKeeper` is the one owner of the mesh in use. Before each step the stepper asks
:meth:`MeshKeeper.reason` whether to remesh and, if so, :meth:`MeshKeeper.replace` builds
the new mesh around the particles, moves the fluid histories onto it and returns the new
state. The rules: on a moving mesh (ALE) :func:`~.ale_rules.remesh_reason` (travel, angle,
area, look-ahead); on a fixed mesh a particle's displacement of ``remesh_fraction`` of its
outline edge; on the default graded mesh the start of a wake (:mod:`~.wake`); a core
closer to a wall or another core than the mesh follows is remeshed once, then stops the
run with the fix (:mod:`~.landing`).
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any

import numpy as np

from .ale_rules import ALE_MIN_ANGLE, ALE_SLIDE_WALLS, REMESH_REASONS, remesh_reason, step_geometry
from .build import CoreSizes, build_coupling
from .errors import SimulationError
from .landing import landing_check
from .mesh_motion import MeshMotion, mesh_quality
from .mesh_repair import REPAIR_AHEAD, REPAIRABLE, flip_plan, transfer_by_flips
from .state import CoupledState
from .transfer import lag, transfer_histories
from .wake import WakeGrading

#: A new mesh's first factorisation is of the Newton Jacobian (when the mesh it replaces
#: held one) if that mesh lived at most this many steps: where the flow outpaces the
#: meshes, the linear operator would stall on the first step and be refreshed at once;
#: on meshes that live longer a Jacobian of the first iterate goes stale within a few
#: steps and is refreshed anyway.
NEWTON_CARRY_STEPS = 4


def fluid_energy(scene, space, u) -> float:
    """Kinetic energy ``rho u.M u / 2`` of fluid velocity DOFs ``u`` on ``space``."""
    return 0.5 * scene.fluid.density * float(u @ (space.M @ u))


class MeshKeeper:
    """The mesh in use, the coupling built on it and the rules that replace it.

    Parameters
    ----------
    scene : Scene
        Mesh options, remeshing rules and effects.
    dem : DEMSystem
        The particles (read: poses, velocities, outlines).
    mesh : meshing.BodyFittedMesh or skfem.MeshTri
        The first mesh; a bare ``MeshTri`` (no recipe) cannot be remeshed.
    cores : CoreSizes
        The particles' core sizes.
    timings : dict
        ``meshing``, ``assembly`` and ``remeshing`` wall times are added to it, and the
        phase times of every coupling it retires.
    coupling_options : dict, optional
        ``terms`` and ``assembly`` for :func:`~.build.build_coupling`.
    poses : (3, K) ndarray, optional
        The particles' poses the mesh was built for (default: the DEM's now).
    """

    def __init__(self, scene, dem, mesh, cores: CoreSizes, timings: dict, *,
                 coupling_options: dict | None = None, poses=None):
        self.scene, self.dem, self.cores, self.timings = scene, dem, cores, timings
        self.coupling_options = dict(coupling_options or {})
        self.remeshes = 0
        self.remesh_energy_ratios: list[float] = []
        #: local repairs instead of remeshes (:meth:`repair`): ``done``, ``refused`` (a
        #: remesh instead), ``flipped`` (edges, over all repairs)
        self.repairs = {"done": 0, "refused": 0, "flipped": 0}
        #: why the moving mesh was remeshed, ``{reason: count}``; ``wake``: the first remesh
        #: after :attr:`wake_grading` found a wake
        self.remesh_reasons = dict.fromkeys((*REMESH_REASONS, "wake"), 0)
        self.worst_mesh = {"min_angle": float("inf"), "min_area_ratio": float("inf"),
                           "steps": 0}
        self.retired_factor_counts = {"factorizations": 0, "jacobian_refreshes": 0}
        self._landing_remeshed = False  # a gap below LANDING_GAP has been remeshed for
        #: a :class:`~.flow_size.FlowSizing` grading every remesh by the flow too (field
        #: meshes); None: by the grains alone
        self.flow_sizing = None
        #: a :class:`~.wake.WakeGrading` refining every remesh of a default-graded mesh
        #: while a particle's Reynolds number is above its threshold; None: never
        self.wake_grading = (WakeGrading() if scene.mesh.wake and scene.mesh.sigma is None
                             and scene.mesh.kind in ("auto", "graded") else None)
        self.motion: MeshMotion | None = None
        self.use(mesh, poses)

    # ------------------------------------------------------------------ the mesh in use
    @property
    def ale(self) -> bool:
        """Whether the mesh moves with the particles (:attr:`Scene.moving_mesh`)."""
        return self.scene.moving_mesh

    @property
    def mesh(self):
        """The fluid mesh (``skfem.MeshTri``; moved with the particles under ALE)."""
        return self.coupling.space.mesh

    @property
    def space(self):
        """The Taylor-Hood discretisation of :attr:`mesh`."""
        return self.coupling.space

    @property
    def factor_counts(self) -> dict:
        """Factorisations over every mesh so far: ``factorizations`` and
        ``jacobian_refreshes``."""
        return {k: v + self.coupling.factor_counts()[k]
                for k, v in self.retired_factor_counts.items()}

    def use(self, mesh, poses=None, since_remesh: int | None = None,
            motion: MeshMotion | None = None) -> None:
        """Make ``mesh`` the mesh in use, built for ``poses`` (default: the DEM's now), with
        a new coupling on it; ``since_remesh``: the steps the replaced mesh lived (a
        short-lived mesh's Newton Jacobian carries over, :data:`NEWTON_CARRY_STEPS`);
        ``motion``: its motion when already made (moving mesh)."""
        old = getattr(self, "coupling", None)
        if old is not None:  # keep the phase times and counts of the coupling being replaced
            for k, v in old.timings.items():
                self.timings[k] = self.timings.get(k, 0.0) + v
            self.retired_factor_counts = self.factor_counts
        t0 = time.perf_counter()
        self.meshed = mesh
        dem = self.dem
        built = getattr(mesh, "mesh", mesh)
        centers = None if poses is None else poses[:2]
        self.coupling = build_coupling(self.scene, built, dem, centers=centers,
                                       **self.coupling_options)
        if old is not None and since_remesh is not None and since_remesh <= NEWTON_CARRY_STEPS:
            self.coupling.inherit_factor_kind(old)
        self.reference_space = self.coupling.space
        self.mesh_poses = (np.vstack([dem.positions, dem.angles[None, :]]) if poses is None
                           else np.array(poses, dtype=float))
        self.travel_poses = self.mesh_poses
        self.motion = None
        if self.ale:
            self.motion = motion or self._motion(built, self.mesh_poses)
        else:  # a fixed mesh's smallest angle, once (:meth:`note_quality`)
            import meshing

            self._built_angle = float(meshing.mesh_stats(built).min_angle)
        self.timings["assembly"] += time.perf_counter() - t0

    def _motion(self, built, poses) -> MeshMotion:
        """The motion of the mesh ``built`` (``skfem.MeshTri``) made for ``poses``."""
        nodes = [np.unique(built.facets[:, built.boundaries[f"particle{k}"]])
                 for k in range(self.dem.n)]
        return MeshMotion(built, nodes, poses, slide_walls=ALE_SLIDE_WALLS)

    def step_geometry(self, state: CoupledState, bdf2, q_n, q_fixed):
        """The moving mesh's callback for one step (:func:`~.ale_rules.step_geometry`)."""
        return step_geometry(self.motion, self.reference_space, state, bdf2, q_n, q_fixed,
                             self.cores)

    def note_quality(self, state: CoupledState) -> None:
        """Fold the mesh a step ended on into :attr:`worst_mesh`."""
        if self.motion is not None:  # a moving mesh
            assert state.nodes_n is not None  # a moving mesh's state holds its vertices
            angle, ratio = mesh_quality(state.nodes_n, self.motion.t, self.motion.area_ref)
        else:  # a fixed mesh is as it was built: its smallest angle, measured once
            angle, ratio = self._built_angle, 1.0
        w = self.worst_mesh
        w["min_angle"] = min(w["min_angle"], angle)
        w["min_area_ratio"] = min(w["min_area_ratio"], ratio)
        w["steps"] += 1

    # ------------------------------------------------------------------ remeshing
    def reason(self, state: CoupledState) -> str | None:
        """Why to remesh before the next step from ``state``, or None.

        ``"wake"`` (a wake starts: its refinement now), an ALE reason
        (:data:`~.ale_rules.REMESH_REASONS`), or ``"moved"`` (a fixed mesh whose
        particles moved ``remesh_fraction`` of their outline edge).
        """
        dem, sc = self.dem, self.scene
        wake = self._wake_options()
        if wake.get("sigma") is not None and wake["sigma"] != self.meshed.recipe.options.get(
                "sigma"):  # a wake starts: its circles now, not at the next remesh
            return "wake"
        moved = self.moved()
        if self.ale:
            dt_ratio = (None if state.dt_prev is None or state.xi_prev is None
                        else sc.time.dt / state.dt_prev)
            return remesh_reason(self.motion, state, moved, dem.particles.q, dt_ratio,
                                 self.cores, sc.remesh_travel)
        return "moved" if np.any(moved > sc.remesh_fraction * self.cores.edge) else None

    def moved(self) -> np.ndarray:
        """How far each particle's outline has moved from where the mesh was built (m;
        a repair keeps the mesh's grading, and this distance)."""
        dem, built = self.dem, self.travel_poses
        return lag(built[:2], built[2], dem.positions, dem.angles, self.cores.radius)

    def replace(self, state: CoupledState, reason: str) -> CoupledState:
        """A new mesh around the particles and the state on it, for ``reason`` (counted in
        :attr:`remesh_reasons` when it is one of them; ``"forced"`` and ``"moved"`` are not).

        Raises
        ------
        RuntimeError
            When remeshing is off, or the mesh has no recipe to be rebuilt from.
        """
        import meshing

        if reason in self.remesh_reasons:
            self.remesh_reasons[reason] += 1
        self._check_remeshable()
        t0 = time.perf_counter()
        s, old = state, self.space
        # moving mesh: the t_{n-1} fields sit at the nodes' t_{n-1} positions
        old_prev = (self.reference_space.moved(s.nodes_prev)
                    if self.ale and s.nodes_prev is not None and s.q_prev is not None else None)
        changes: dict[str, Any] = {}
        if self.flow_sizing is not None:
            if self.meshed.recipe.kind != "field":
                raise ValueError(f"flow_sizing: needs a 'field' mesh ([mesh] kind = "
                                 f"\"field\"), the mesh is {self.meshed.recipe.kind!r}")
            changes["size"] = self.flow_sizing(self.space, s.u_n)
        new_mesh = meshing.remesh(self.meshed, self.dem.core_outlines(), **changes,
                                  **self._wake_options())
        self.timings["meshing"] += time.perf_counter() - t0
        self.use(new_mesh, since_remesh=s.since_remesh)
        t0 = time.perf_counter()
        new = self._transfer(s, old, old_prev)
        # interpolation must not create kinetic energy out of nothing: record the ratio
        e_old = fluid_energy(self.scene, old, s.u_n)
        if e_old > 0:
            self.remesh_energy_ratios.append(fluid_energy(self.scene, self.space, new.u_n) / e_old)
        self.timings["remeshing"] += time.perf_counter() - t0
        self.remeshes += 1
        return new

    def repair(self, state: CoupledState, reason: str) -> CoupledState | None:
        """The state on the mesh in use with a few edges flipped
        (:mod:`~.mesh_repair`), when that answers ``reason`` and no other reason is left;
        None when it cannot (then :meth:`replace`). Counted in :attr:`repairs`."""
        s, motion = state, self.motion
        if (motion is None or reason not in REPAIRABLE or s.nodes_n is None
                or not self.scene.repairs_mesh):
            return None
        t0 = time.perf_counter()
        q = self.dem.particles.q
        dt_ratio = None if s.dt_prev is None else self.scene.time.dt / s.dt_prev
        ahead = []
        if s.q_prev is not None and dt_ratio is not None:  # remesh_reason's extrapolation
            step = (q - s.q_prev) * dt_ratio
            ahead = [motion.positions(q + k * step) for k in range(1, REPAIR_AHEAD + 1)]
        t_new, changed = flip_plan(motion.t, s.nodes_prev, s.nodes_n, ahead)
        if changed.size == 0 or any(  # a triangle the rule rejects is left: a new mesh
                mesh_quality(p, t_new, motion.area_ref)[0] < ALE_MIN_ANGLE
                for p in (s.nodes_n, *ahead[:1])):
            self.repairs["refused"] += 1
            self.timings["meshing"] += time.perf_counter() - t0
            return None
        from meshing.flips import with_triangles  # meshing: imported when a mesh is repaired

        built = with_triangles(self.meshed.mesh, t_new, p=s.nodes_n)
        new_motion = self._motion(built, q)
        left = remesh_reason(new_motion, s, self.moved(), q, dt_ratio, self.cores,
                             self.scene.remesh_travel)
        self.timings["meshing"] += time.perf_counter() - t0
        if left is not None:
            self.repairs["refused"] += 1
            return None
        old, travel = self.space, self.travel_poses
        self.use(replace(self.meshed, mesh=built), poses=q, since_remesh=s.since_remesh,
                 motion=new_motion)
        self.travel_poses = travel
        t0 = time.perf_counter()
        new = replace(s, **transfer_by_flips(s, old, self.space, changed,
                                             free=self.coupling.op.free), since_remesh=0)
        self.timings["remeshing"] += time.perf_counter() - t0
        self.repairs["done"] += 1
        self.repairs["flipped"] += int(changed.size) // 2
        return new

    def _transfer(self, s: CoupledState, old, old_prev) -> CoupledState:
        """The fluid histories of ``s`` moved from ``old`` onto the mesh now in use."""
        nodes = {}
        new_prev = None
        if self.motion is not None:  # a moving mesh
            nodes = {"nodes_n": self.mesh.p, "nodes_prev": None}  # built where the particles are
            if old_prev is not None and s.q_prev is not None:
                # the new mesh's own t_{n-1} configuration: its outlines where the particles
                # were then, so the mesh velocity stays the particles' velocity at the
                # outlines and the t_{n-1} history is the field at those points then
                nodes["nodes_prev"] = self.motion.positions(s.q_prev)
                new_prev = self.reference_space.moved(nodes["nodes_prev"])
        # projected divergence-free on the moving mesh only: on the fixed mesh the particle
        # boundary jumps at a remesh, and projecting there changed a colliding pair's
        # momentum
        fields = transfer_histories(s, old, self.space, old_prev=old_prev, new_prev=new_prev,
                                    project=self.coupling.op if self.ale else None)
        return replace(s, **fields, **nodes, since_remesh=0)

    def _check_remeshable(self) -> None:
        moved = self.moved().max()
        if not self.scene.effects.remeshing:
            raise RuntimeError(
                f"particles moved {moved:.3g} m, more than "
                f"remesh_fraction x edge length, and effects.remeshing is off")
        if getattr(self.meshed, "recipe", None) is None:
            raise RuntimeError(
                f"particles moved {moved:.3g} m, more than remesh_fraction x edge "
                "length, and the mesh given to the simulation has no recipe to remesh it "
                "(pass a meshing.BodyFittedMesh from meshing.build)")

    def _wake_options(self) -> dict:
        """The builder options :attr:`wake_grading` asks of the next remesh (``{}``: none,
        for a mesh that is not a remeshable ``graded`` one, with remeshing off, or
        without the rule)."""
        recipe = getattr(self.meshed, "recipe", None)
        if (self.wake_grading is None or recipe is None or recipe.kind != "graded"
                or not self.scene.effects.remeshing):
            return {}
        return self.wake_grading.changes(self.dem.velocities, self.cores.radius,
                                         self.scene.fluid.kinematic_viscosity)

    def landing(self, state: CoupledState, contacts_active: bool) -> CoupledState:
        """``state``, or the state on a new mesh when a core came closer to a wall or another
        core than the mesh follows (:mod:`~.landing`) for the first time.

        Raises
        ------
        SimulationError
            With one line and the fix, when it is closer again after that remesh (or
            cannot be remeshed).
        """
        msg = landing_check(self.dem, self.scene.domain, self.cores.edge, contacts_active,
                            state.t)
        if msg is None:
            self._landing_remeshed = False
            return state
        if (self._landing_remeshed or not self.scene.effects.remeshing
                or getattr(self.meshed, "recipe", None) is None):
            raise SimulationError(msg)
        self._landing_remeshed = True
        return self.replace(state, "forced")
