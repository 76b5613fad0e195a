"""Simulation: builds what a scene calls for and runs it.

The per-step pipeline (monolithic coupling, the default):

1. external forces: buoyancy-reduced gravity ``m g - rho_f A_core g`` and the
   contact forces of the last DEM evaluation;
2. the coupled BDF2 corrector (fluid + rigid particle velocities, Eq. 1);
3. particle positions: the same BDF2 formula on the positions, or, when
   contacts are active, a subcycled DEM advance with the hydrodynamic force
   of step 2 held;
4. remesh when a particle has moved by ``remesh_fraction`` of its outline
   edge length since the mesh was built, transferring ``u_n`` and ``u_{n-1}``;
5. history row, VTU frames every ``vtu_every`` steps.

A dry scene (no fluid) builds no mesh and only advances the DEM.
"""

from __future__ import annotations

import json
import math
import time
from collections import defaultdict
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from .coupled_run import SimulationError, run_coupled
from .dem import DEMSystem
from .dem.output import write_outlines_vtu
from .history import History
from .io import PVDSeries, atomic_write
from .scene import Scene
from .simulation_setup import (
    build_coupling,
    build_mesh,
    contacts_needed,
    outline_areas,
    outline_edge,
    scene_warnings,
)


@dataclass
class SimulationResult:
    """What a run produced.

    Attributes
    ----------
    history : History
        Per-step table (``history.t``, ``history.vy``, ...).
    summary : dict
        Effects, mesh counts, final state, wall times per phase, warnings.
    output_dir : Path or None
    """

    history: History
    summary: dict
    output_dir: Path | None = None
    files: list = field(default_factory=list)


class Simulation:
    """A coupled (or dry) simulation of a :class:`~skfem_granular.scene.Scene`.

    Parameters
    ----------
    scene : Scene or str or Path
        The scene, or a TOML file to read it from.
    output_dir : str or Path, optional
        Overrides ``scene.output_dir``; ``None`` in both writes nothing.
    mesh : skfem.MeshTri, optional
        Use this fluid mesh instead of building one from ``scene.mesh``; it
        must have the boundaries ``"wall"`` and ``"particle0"``, ... around
        the particle cores (as :mod:`meshing` makes them).
    """

    def __init__(self, scene: Scene, output_dir=None, *, mesh=None):
        if not isinstance(scene, Scene):
            scene = Scene.from_toml(scene)
        self.scene = scene
        self.timings = defaultdict(float)
        out = output_dir if output_dir is not None else scene.output_dir
        self.output_dir = None if out is None else Path(out)
        if self.output_dir is not None:
            from .io import _check_writable

            _check_writable(self.output_dir / "summary.json")
        eff = scene.effects
        g = np.asarray(scene.gravity) if eff.gravity else np.zeros(2)
        self.g = g
        self.dem = DEMSystem.in_box(
            [p.to_dem() for p in scene.particles],
            scene.domain,
            scene.wall_thickness,
            law=scene.contact_law,
            gravity=g,
            dt=scene.time.dem_dt,
        )
        self.contacts_active = (
            contacts_needed(scene, self.dem) if eff.contacts == "auto" else bool(eff.contacts)
        )
        self.warnings = scene_warnings(scene, self.dem, self.contacts_active)
        self.remeshes = 0
        self.remesh_energy_ratios = []
        self.retries = 0
        self.rejections = 0
        self.euler_steps = 0  # backward-Euler steps taken because of contacts
        self.failure = None
        self.last_good = None
        self._resume = None
        if not scene.dry:
            t0 = time.perf_counter()
            self.mesh = build_mesh(scene, self.dem.core_outlines()) if mesh is None else mesh
            self.timings["meshing"] += time.perf_counter() - t0
            self._new_coupling()

    @classmethod
    def resume(cls, directory, t_end: float | None = None) -> Simulation:
        """Continue a run from the ``checkpoint.pkl`` in ``directory``.

        Parameters
        ----------
        directory : str or Path
            Output directory of a run with ``output.checkpoint_every > 0``.
        t_end : float, optional
            New end time (default: the scene's).

        Returns
        -------
        Simulation
            Ready to :meth:`run` from the checkpointed step; output continues
            in ``directory``.
        """
        from . import checkpoint

        data = checkpoint.load(directory)
        scene = data["scene"]
        if t_end is not None:
            scene = replace(scene, time=replace(scene.time, t_end=t_end))
        sim = cls(scene, output_dir=directory, mesh=data["mesh"])
        sim.dem.restore_state(data["dem"])
        if not scene.dry:
            sim._new_coupling(centers=data["mesh_centers"], angles=data["mesh_angles"])
        sim.remeshes = data["counters"]["remeshes"]
        sim.retries = data["counters"]["retries"]
        sim.rejections = data["counters"].get("rejections", 0)
        sim.euler_steps = data["counters"].get("euler_steps", 0)
        sim._resume = data
        return sim

    # ------------------------------------------------------------------ setup
    def _new_coupling(self, centers=None, angles=None):
        old = getattr(self, "coupling", None)
        if old is not None:  # keep the phase times of the coupling being replaced
            for k, v in old.timings.items():
                self.timings[k] += v
        t0 = time.perf_counter()
        self.coupling = build_coupling(self.scene, self.mesh, self.dem, centers=centers)
        self.space = self.coupling.space
        self.mesh_centers = self.dem.positions.copy() if centers is None else np.array(centers)
        self.mesh_angles = self.dem.angles.copy() if angles is None else np.array(angles)
        # body-frame outlines: the same numbers whatever the particles' current pose
        # (a resumed run must see bit-identical buoyancy)
        p = self.dem.particles
        cores = [p.core_local[k, : p.core_count[k]].T for k in range(self.dem.n)]
        self.core_area = outline_areas(cores)
        self.edge = np.array([outline_edge(c, self.scene.mesh.delta_l) for c in cores])
        self.radius = np.array(
            [np.linalg.norm(c - c.mean(axis=1, keepdims=True), axis=0).max() for c in cores]
        )
        self.timings["assembly"] += time.perf_counter() - t0

    def _external(self):
        """Buoyancy-reduced gravity ``(m - rho_f A_core) g``."""
        rho_f = 0.0 if self.scene.dry else self.scene.fluid.density
        F = np.outer(self.g, self.dem.mass) - rho_f * np.outer(self.g, self.core_area)
        return F, np.zeros(self.dem.n)

    def _dem_predictor(self, dt, F_fluid, T_fluid):
        """Subcycle the DEM over ``dt`` with the fluid force held.

        Returns the mean contact force ``(2, N)`` and torque ``(N,)`` over the
        step (from the momentum change, so impulses of short contacts count in
        full) and the positions ``(3, N)`` at the end of the step.
        """
        dem = self.dem
        rho_f = self.scene.fluid.density
        buoyancy = rho_f * np.outer(self.g, self.core_area)
        dem.external_force[...] = F_fluid - buoyancy
        dem.external_torque[...] = T_fluid
        v0 = dem.velocities.copy()
        w0 = dem.angular_velocities.copy()
        dem.advance(dt)
        F_c = (
            dem.mass * (dem.velocities - v0) / dt - np.outer(self.g, dem.mass) - dem.external_force
        )
        T_c = dem.inertia * (dem.angular_velocities - w0) / dt - dem.external_torque
        q = np.vstack([dem.positions, dem.angles[None, :]]).copy()
        return F_c, T_c, q

    # ------------------------------------------------------------------ run
    def run(self, progress: bool | None = None) -> SimulationResult:
        """Run to ``scene.time.t_end``; returns a :class:`SimulationResult`.

        Parameters
        ----------
        progress : bool, optional
            Show a tqdm progress bar (default: when the run has > 50 steps).
        """
        sc = self.scene
        t_start = time.perf_counter()
        dt = sc.time.dt
        n_steps = max(1, int(math.ceil(sc.time.t_end / dt - 1e-9)))
        hist = History(self.dem.n)
        series = self._open_series()
        start, k0 = None, 0
        if self._resume is not None:
            hist.rows = list(self._resume["history"])
            for name, frames in self._resume["frames"].items():
                if series is not None and series.get(name) is not None:
                    series[name].frames = list(frames)
            start, k0 = self._resume["state"], self._resume["k"]
            n_steps = max(0, n_steps - k0)
        show = n_steps > 50 if progress is None else progress
        if show:  # tqdm.auto picks the notebook widget; plain tqdm when it is hidden
            from tqdm.auto import tqdm
        else:
            from tqdm import tqdm
        bar = tqdm(
            total=n_steps,
            disable=not show,
            desc=sc.name,
            unit="step",
        )
        try:
            # many small BLAS calls (norms, dots) next to SuperLU: OpenBLAS threads only
            # spin against each other on 2 cores (measured: 16 ms instead of 5 us per norm)
            with threadpool_limits(limits=1, user_api="blas"):
                if sc.dry:
                    self._run_dry(n_steps, dt, hist, series, bar, k0=k0)
                else:
                    run_coupled(self, hist, series, bar, start=start, k0=k0)
        except (SimulationError, FloatingPointError) as exc:
            self.failure = str(exc)
            if not sc.dry and self.last_good is not None and series is not None:
                self._write_frame(series, self.last_good.t, x=self.last_good.x)
            raise SimulationError(f"{exc}; history and last good state written to "
                                   f"{self.output_dir}") from exc
        finally:
            bar.close()
            if not sc.dry:
                for k, v in self.coupling.timings.items():
                    self.timings[k] += v
                self.coupling.timings = dict.fromkeys(self.coupling.timings, 0.0)
            self.timings["total"] = time.perf_counter() - t_start
            summary = self.summary(hist)
            files = self._finish(hist, summary)
        return SimulationResult(hist, summary, self.output_dir, files)

    def _open_series(self):
        if self.output_dir is None:
            return None
        d = self.output_dir
        return {
            "flow": None if self.scene.dry else PVDSeries(d / "flow.pvd"),
            "particles": PVDSeries(d / "particles.pvd"),
        }

    def _write_frame(self, series, t, x=None):
        if series is None:
            return
        t0 = time.perf_counter()
        dem = self.dem
        series["particles"].write(t, lambda f: write_outlines_vtu(f, dem))
        if x is not None:
            flow = self.coupling.flow(x)
            series["flow"].write(t, flow.save)
        self.timings["output"] += time.perf_counter() - t0

    def _record(self, hist, t, dt, its, acc, F, T, u=None, error=float("nan")):
        dem = self.dem
        hist.append(
            t,
            dt,
            its,
            fluid_energy=float("nan") if u is None else self.fluid_energy(u),
            error=error,
            x=dem.positions[0],
            y=dem.positions[1],
            angle=dem.angles,
            vx=dem.velocities[0],
            vy=dem.velocities[1],
            omega=dem.angular_velocities,
            ax=acc[0],
            ay=acc[1],
            Fx=F[0],
            Fy=F[1],
            torque=T,
            contacts=dem.contact_count(),
        )

    def _run_dry(self, n_steps, dt, hist, series, bar, k0=0):
        from . import checkpoint

        dem = self.dem
        if k0 == 0:
            self._write_frame(series, 0.0)
        v_old = dem.velocities.copy()
        zeros = np.zeros(dem.n)
        every = self.scene.checkpoint_every
        for k in range(k0, k0 + n_steps):
            t0 = time.perf_counter()
            dem.advance(dt)
            self.timings["dem"] += time.perf_counter() - t0
            acc = (dem.velocities - v_old) / dt
            v_old = dem.velocities.copy()
            self._record(hist, dem.t, dt, 0, acc, np.zeros((2, dem.n)), zeros)
            if self._frame_due(k - k0, n_steps):
                self._write_frame(series, dem.t)
            if every and self.output_dir is not None and (k + 1) % every == 0:
                checkpoint.save(self, None, k + 1, hist, series)
            bar.update()

    def _frame_due(self, k, n_steps):
        every = self.scene.vtu_every
        return k == n_steps - 1 or (every > 0 and (k + 1) % every == 0)

    def _frame_due_time(self, k, t):
        every = self.scene.vtu_every
        last = t >= self.scene.time.t_end - 1e-9 * self.scene.time.dt
        return last or (every > 0 and k % every == 0)

    def _maybe_remesh(self, u_n, u_prev, p_n, *velocities):
        """Remesh when a particle moved too far; returns ``u_n, u_prev, p_n`` and the
        further ``velocities`` (time derivatives, None allowed) on the mesh in use."""
        from .motion import FieldTransfer, lag

        dem, sc = self.dem, self.scene
        moved = lag(self.mesh_centers, self.mesh_angles, dem.positions, dem.angles, self.radius)
        if not np.any(moved > sc.remesh_fraction * self.edge):
            return (u_n, u_prev, p_n, *velocities)
        if not sc.effects.remeshing:
            raise RuntimeError(
                f"particles moved {moved.max():.3g} m, more than "
                f"remesh_fraction x edge length, and effects.remeshing is off"
            )
        import meshing

        t0 = time.perf_counter()
        old = self.space
        self.mesh = meshing.remesh(self.mesh, dem.core_outlines())
        self.timings["meshing"] += time.perf_counter() - t0
        self._new_coupling()
        t0 = time.perf_counter()
        tr = FieldTransfer(old, self.space)
        e_old = 0.5 * self.scene.fluid.density * float(u_n @ (old.M @ u_n))
        u_n = tr.velocity(u_n)
        u_prev = None if u_prev is None else tr.velocity(u_prev)
        velocities = [None if v is None else tr.velocity(v) for v in velocities]
        p_n = tr.pressure(p_n)
        # interpolation must not create kinetic energy out of nothing: record the ratio
        if e_old > 0:
            self.remesh_energy_ratios.append(self.fluid_energy(u_n) / e_old)
        self.timings["remeshing"] += time.perf_counter() - t0
        self.remeshes += 1
        return (u_n, u_prev, p_n, *velocities)

    def fluid_energy(self, u) -> float:
        """Kinetic energy ``rho u.M u / 2`` of a velocity on the current mesh (J/m)."""
        return 0.5 * self.scene.fluid.density * float(u @ (self.space.M @ u))

    # ------------------------------------------------------------------ report
    def summary(self, hist: History) -> dict:
        """Run summary: effects, mesh, final state, wall times, warnings."""
        sc = self.scene
        eff = sc.effects
        active = {
            "fluid": not sc.dry,
            "gravity": eff.gravity,
            "convection": (not sc.dry) and eff.convection,
            "contacts": self.contacts_active,
            "rotation": eff.rotation,
            "remeshing": (not sc.dry) and eff.remeshing,
        }
        out = {
            "scene": sc.name,
            "effects": active,
            "coupling": None if sc.dry else sc.coupling,
            "particles": self.dem.n,
            "steps": len(hist),
            "t_end": float(hist.t[-1]) if len(hist) else 0.0,
            "dt": sc.time.dt,
            "remeshes": self.remeshes,
            "retries": self.retries,
            "rejections": self.rejections,
            "euler_steps_at_contacts": self.euler_steps,
            "adaptive": sc.time.adaptive,
            "dt_range": ([float(hist.dt.min()), float(hist.dt.max())] if len(hist) else None),
            "remesh_energy_ratio_max": max(self.remesh_energy_ratios, default=None),
            "failed": self.failure,
            "warnings": list(self.warnings),
            "wall_time": {k: round(v, 6) for k, v in self.timings.items()},
        }
        if not sc.dry:
            import meshing

            st = meshing.mesh_stats(self.mesh)
            out["mesh"] = {
                "kind": sc.mesh.kind,
                "vertices": st.n_vertices,
                "p2_nodes": st.n_p2_nodes,
                "triangles": st.n_triangles,
                "dofs": int(self.space.N),
                "min_angle": float(st.min_angle),
            }
        if len(hist):
            out["final"] = {
                "x": hist.x[-1].tolist(),
                "y": hist.y[-1].tolist(),
                "vx": hist.vx[-1].tolist(),
                "vy": hist.vy[-1].tolist(),
                "omega": hist.omega[-1].tolist(),
            }
        return out

    def _finish(self, hist, summary):
        if self.output_dir is None:
            return []
        d = self.output_dir
        hist.to_csv(d / "history.csv")
        text = json.dumps(summary, indent=2)
        atomic_write(d / "summary.json", lambda tmp: Path(tmp).write_text(text))
        return [d / "history.csv", d / "summary.json"]
