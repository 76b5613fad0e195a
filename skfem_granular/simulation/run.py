"""Simulation: builds what a scene calls for, drives its stepper, records what it yields.

A scene with fluid gets a :class:`~skfem_granular.coupled.CoupledStepper`
(mesh, coupling, DEM, remeshing); a dry scene a
:class:`~skfem_granular.simulation.dry.DryStepper` (the DEM alone, no mesh).
:meth:`Simulation.evolve` is the stepper's generator with the recording added:
after every accepted step it appends the history row, writes the VTU frames
every ``vtu_every`` steps and a checkpoint every ``checkpoint_every`` steps.
``history.csv`` grows as the run goes: rows are appended and synced to the
disk with every frame, every checkpoint, at least every
:data:`FLUSH_SECONDS` of wall time and when the loop ends, so a run killed
even with SIGKILL leaves a readable history up to its last flush. When the
loop ends, however it ends (completed, failed, broken off, or stopped by
SIGINT/SIGTERM), the history is complete and ``summary.json`` is written with
the run's ``status``. :meth:`Simulation.run` drives that generator to the end.

SIGINT and SIGTERM (in the main thread) stop a run at the end of the current
step: the step is recorded, a checkpoint is written (so the run can be
resumed, bit for bit), the history and the summary are written, and the
generator ends as if the run had reached its end (``summary["status"] ==
"stopped"``, ``summary["stopped_by"] == "SIGTERM"``). A second signal of the
same kind acts as it did before the run (Ctrl-C twice interrupts at once).
The previous handlers are restored when the loop ends.
"""

from __future__ import annotations

import json
import math
import os
import signal
import threading
import time
from collections import defaultdict
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from ..coupled.build import build_mesh
from ..coupled.stepper import CoupledStepper, SimulationError
from ..dem import DEMSystem
from ..dem.output import write_outlines_vtu
from ..io import CSVLog, History, PVDSeries, atomic_write, check_writable, remove_partial_files
from ..scene import Scene
from .dry import DryStepper
from .effects import contacts_needed, scene_warnings

#: The history file is synced at least this often (wall seconds) besides frames and checkpoints.
FLUSH_SECONDS = 10.0

#: The signals that stop a run at the end of its current step.
STOP_SIGNALS = ("SIGINT", "SIGTERM")


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
    files : list of Path
        The history and summary files written.
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
    mesh : meshing.BodyFittedMesh or skfem.MeshTri, optional
        Use this fluid mesh instead of building one from ``scene.mesh``; it
        must have the boundaries ``"wall"`` and ``"particle0"``, ... around
        the particle cores (as :mod:`meshing` makes them). A bare ``MeshTri``
        has no recipe: a run that needs a remesh then stops with an error.

    Examples
    --------
    >>> sim = Simulation(Scene.bundled("single_particle"))   # doctest: +SKIP
    >>> for t, step in sim.evolve():                          # doctest: +SKIP
    ...     print(t, step.force[1, 0], sim.dem.velocities[1, 0])
    """

    def __init__(self, scene: Scene, output_dir=None, *, mesh=None):
        if not isinstance(scene, Scene):
            scene = Scene.from_toml(scene)
        self.scene = scene
        self.timings = defaultdict(float)
        out = output_dir if output_dir is not None else scene.output_dir
        self.output_dir = None if out is None else Path(out)
        if self.output_dir is not None:
            check_writable(self.output_dir / "summary.json")
        eff = scene.effects
        g = np.asarray(scene.gravity) if eff.gravity else np.zeros(2)
        self.dem = DEMSystem.in_box(
            [p.to_dem() for p in scene.particles],
            scene.domain,
            scene.wall_thickness,
            law=scene.contact_law,
            gravity=g,
            dt=scene.time.dem_dt,
            overlap_tolerance=scene.overlap_tolerance,
        )
        self.contacts_active = (
            contacts_needed(scene, self.dem) if eff.contacts == "auto" else bool(eff.contacts)
        )
        self.warnings = scene_warnings(scene, self.dem, self.contacts_active)
        self.failure = None
        self.status = "not started"
        self.stopped_by = None
        self.history = History(self.dem.n)
        self.steps_done = 0
        self.result: SimulationResult | None = None
        self._resumed_frames = {}
        if scene.dry:
            self.stepper = DryStepper(scene, self.dem, self.timings)
        else:
            t0 = time.perf_counter()
            mesh = build_mesh(scene, self.dem.core_outlines()) if mesh is None else mesh
            self.timings["meshing"] += time.perf_counter() - t0
            self.stepper = CoupledStepper(scene, self.dem, mesh,
                                          contacts_active=self.contacts_active,
                                          timings=self.timings)

    @classmethod
    def resume(cls, directory, t_end: float | None = None) -> Simulation:
        """Continue a run from the checkpoint in ``directory``.

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
            in ``directory`` (``history.csv`` rewritten to the checkpoint's rows
            when the run starts, ``.partial-*`` left-overs of a killed run removed).

        Raises
        ------
        ValueError
            One line naming the field, for a missing, foreign, older (pickle: not read) or
            inconsistent checkpoint (:func:`~skfem_granular.simulation.checkpoint.load`).
        """
        from . import checkpoint

        data = checkpoint.load(directory)
        scene = data["scene"]
        if t_end is not None:
            scene = replace(scene, time=replace(scene.time, t_end=t_end))
        saved = data["stepper"]
        sim = cls(scene, output_dir=directory, mesh=saved.get("mesh"))
        # the entries this version's stepper and DEM hand over, no more and no fewer
        where = f"checkpoint {str(Path(directory) / checkpoint.FILENAME)!r}"
        checkpoint.check_entries(data["dem"], sim.dem.save_state(), "dem", where)
        checkpoint.check_entries(saved, sim.stepper.checkpoint_state(), "stepper", where)
        remove_partial_files(directory)  # what a killed writer left behind
        sim.dem.restore_state(data["dem"])
        if scene.dry:
            sim.stepper.steps_taken = saved["steps_taken"]
        else:
            sim.stepper = CoupledStepper.from_checkpoint_state(
                scene, sim.dem, saved, contacts_active=sim.contacts_active, timings=sim.timings)
        sim.history.rows = list(data["history"])
        sim.steps_done = data["k"]
        sim._resumed_frames = data["frames"]
        return sim

    # ------------------------------------------------------------------ views
    def _coupled(self, name):
        if self.scene.dry:
            raise AttributeError(f"a dry scene has no {name}")
        return self.stepper

    @property
    def mesh(self):
        """The fluid mesh in use (``skfem.MeshTri``); a dry scene has none."""
        return self._coupled("mesh").mesh

    @property
    def space(self):
        """The Taylor-Hood discretisation on :attr:`mesh`."""
        return self._coupled("space").space

    @property
    def coupling(self):
        """The fluid-particle coupling on :attr:`mesh`."""
        return self._coupled("coupling").coupling

    @property
    def remeshes(self) -> int:
        return 0 if self.scene.dry else self.stepper.remeshes

    @property
    def retries(self) -> int:
        """Step halvings after corrector failures."""
        return 0 if self.scene.dry else self.stepper.retries

    @property
    def rejections(self) -> int:
        """Steps rejected by the error control (adaptive runs)."""
        return 0 if self.scene.dry else self.stepper.rejections

    @property
    def euler_steps(self) -> int:
        """Backward-Euler steps taken because of contacts."""
        return 0 if self.scene.dry else self.stepper.euler_steps

    @property
    def remesh_energy_ratios(self) -> list:
        """Fluid kinetic energy after / before each transfer onto a new mesh."""
        return [] if self.scene.dry else self.stepper.remesh_energy_ratios

    @property
    def last_good(self):
        """The stepper's state after the last accepted step (coupled scenes)."""
        return self._coupled("state").state

    # ------------------------------------------------------------------ run
    def evolve(self, progress: bool | None = False):
        """Advance to ``scene.time.t_end``; a generator yielding ``(t, step)`` per step.

        ``step`` is the :class:`~skfem_granular.coupled.state.StepReport` of the
        accepted step; the particles are in :attr:`dem`, the fluid in
        ``self.stepper.flow()``. History rows, frames and checkpoints are written as
        by :meth:`run` (``history.csv`` synced with every frame and checkpoint); when
        the loop ends (exhausted, closed, failed, or stopped by SIGINT/SIGTERM, see
        the module notes) the history and summary files are complete and
        :attr:`result` is set. BLAS runs on one
        thread while the generator is open (many small BLAS calls next to SuperLU:
        OpenBLAS threads only spin against each other on 2 cores, measured 16 ms
        instead of 5 us per norm).

        Parameters
        ----------
        progress : bool, optional
            Show a tqdm progress bar (``None``: when the run has > 50 steps).

        Raises
        ------
        SimulationError
            When a step does not converge; the history and the last good state
            are written first.
        """
        sc = self.scene
        t_start = time.perf_counter()
        n_steps = max(1, int(math.ceil(sc.time.t_end / sc.time.dt - 1e-9)))
        n_steps = max(0, n_steps - self.steps_done)
        series = self._open_series()
        show = n_steps > 50 if progress is None else progress
        if show:  # tqdm.auto picks the notebook widget; plain tqdm when it is hidden
            from tqdm.auto import tqdm
        else:
            from tqdm import tqdm
        bar = tqdm(total=n_steps, disable=not show, desc=sc.name, unit="step")
        every = sc.checkpoint_every
        log = None
        self.status, self.stopped_by = "running", None
        caught = self._catch_signals()
        try:
            log = self._open_log()
            with threadpool_limits(limits=1, user_api="blas"):
                if self.steps_done == 0:
                    self._write_frame(series, 0.0)
                for t, step in self.stepper.evolve():
                    self.steps_done += 1
                    self._record(step)
                    checkpointed = False
                    if self._frame_due(self.steps_done, t):
                        self._write_frame(series, t)
                        self._flush(log)
                    if every and self.output_dir is not None and self.steps_done % every == 0:
                        self._checkpoint(series, log)
                        checkpointed = True
                    elif log is not None and time.monotonic() - self._flushed > FLUSH_SECONDS:
                        self._flush(log)
                    bar.update(1)
                    yield t, step
                    if self.stopped_by is not None:  # SIGINT/SIGTERM during the step
                        if self.output_dir is not None and not checkpointed:
                            self._checkpoint(series, log)
                        self.status = "stopped"
                        break
                else:
                    self.status = "completed"
        except (SimulationError, FloatingPointError) as exc:
            self.failure = str(exc)
            self.status = "failed"
            if not sc.dry:
                self._write_frame(series, self.stepper.state.t)
            raise SimulationError(f"{exc}; history and last good state written to "
                                  f"{self.output_dir}") from exc
        except GeneratorExit:
            self.status = "closed"  # the caller broke off the loop
            raise
        except BaseException as exc:  # KeyboardInterrupt (a second Ctrl-C), errors
            self.status = "failed"
            self.failure = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
            raise
        finally:
            self._restore_signals(caught)
            bar.close()
            self.stepper.collect_timings()
            self.timings["total"] += time.perf_counter() - t_start
            summary = self.summary(self.history)
            self.result = SimulationResult(self.history, summary, self.output_dir,
                                           self._finish(log, summary))

    def run(self, progress: bool | None = None) -> SimulationResult:
        """Run to ``scene.time.t_end``; returns a :class:`SimulationResult`.

        Parameters
        ----------
        progress : bool, optional
            Show a tqdm progress bar (default: when the run has > 50 steps).
        """
        for _ in self.evolve(progress):
            pass
        return self.result

    # ------------------------------------------------------------------ output
    def _open_log(self):
        """The live ``history.csv``: header and the rows so far (a resumed run's), then appends."""
        self._flushed = time.monotonic()
        if self.output_dir is None:
            return None
        return CSVLog(self.history, self.output_dir / "history.csv")

    def _flush(self, log):
        if log is not None:
            t0 = time.perf_counter()
            log.flush()
            self._flushed = time.monotonic()
            self.timings["output"] += time.perf_counter() - t0

    def _checkpoint(self, series, log):
        """History synced first, then the checkpoint: the file always has its rows."""
        from . import checkpoint

        self._flush(log)
        t0 = time.perf_counter()
        checkpoint.save(self, self.steps_done, series)
        self.timings["output"] += time.perf_counter() - t0

    def _catch_signals(self) -> dict:
        """Stop at the end of the current step on SIGINT/SIGTERM (main thread only)."""
        if threading.current_thread() is not threading.main_thread():
            return {}
        caught = {}

        def stop(signum, frame):
            name = signal.Signals(signum).name
            if self.stopped_by is None:
                self.stopped_by = name
            prev = caught.get(signum)
            if prev is not None:  # a second one acts as before the run
                signal.signal(signum, prev)
            try:
                os.write(2, f"\nskfem-granular: {name}: stopping at the end of this step "
                            f"(again: stop at once)\n".encode())
            except OSError:
                pass

        for name in STOP_SIGNALS:
            sig = getattr(signal, name)
            prev = signal.getsignal(sig)
            if prev is None or prev == signal.SIG_IGN:  # not Python's, or ignored: left alone
                continue
            caught[sig] = prev
            signal.signal(sig, stop)
        self._stop_handler = stop
        return caught

    def _restore_signals(self, caught: dict) -> None:
        for sig, prev in caught.items():
            if signal.getsignal(sig) is self._stop_handler:
                signal.signal(sig, prev)

    def _open_series(self):
        if self.output_dir is None:
            return None
        d = self.output_dir
        series = {"flow": None if self.scene.dry else PVDSeries(d / "flow.pvd"),
                  "particles": PVDSeries(d / "particles.pvd")}
        for name, frames in self._resumed_frames.items():
            if series.get(name) is not None:
                series[name].frames = list(frames)
        return series

    def _write_frame(self, series, t):
        if series is None:
            return
        t0 = time.perf_counter()
        dem = self.dem
        series["particles"].write(t, lambda f: write_outlines_vtu(f, dem))
        if series["flow"] is not None:
            series["flow"].write(t, self.stepper.flow().save)
        self.timings["output"] += time.perf_counter() - t0

    def _frame_due(self, k, t):
        every = self.scene.vtu_every
        last = t >= self.scene.time.t_end - 1e-9 * self.scene.time.dt
        return last or (every > 0 and k % every == 0)

    def _record(self, step):
        dem = self.dem
        acc = step.acceleration
        self.history.append(
            step.t, step.dt, step.iterations, fluid_energy=step.fluid_energy,
            error=step.error, x=dem.positions[0], y=dem.positions[1], angle=dem.angles,
            vx=dem.velocities[0], vy=dem.velocities[1], omega=dem.angular_velocities,
            ax=acc[0], ay=acc[1], Fx=step.force[0], Fy=step.force[1], torque=step.torque,
            contacts=dem.contact_count())

    def fluid_energy(self) -> float:
        """Kinetic energy ``rho u.M u / 2`` of the fluid now (J per unit depth)."""
        return self._coupled("fluid").fluid_energy()

    # ------------------------------------------------------------------ report
    def summary(self, hist: History) -> dict:
        """Run summary: effects, mesh, final state, wall times, warnings.

        ``status`` is ``"completed"``, ``"stopped"`` (by the signal named in
        ``stopped_by``), ``"failed"`` (the reason in ``failed``), ``"closed"`` (the
        caller broke off :meth:`evolve`'s loop) or ``"running"``.
        """
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
        ratios = self.remesh_energy_ratios
        out = {
            "scene": sc.name,
            "effects": active,
            "coupling": None if sc.dry else sc.coupling,
            "mesh_motion": None if sc.dry else ("ale" if sc.moving_mesh else "fixed"),
            "particles": self.dem.n,
            "imposed_motion": [int(k) for k in np.flatnonzero(self.dem.imposed)],
            "steps": len(hist),
            "t_end": float(hist.t[-1]) if len(hist) else 0.0,
            "dt": sc.time.dt,
            "remeshes": self.remeshes,
            "remesh_reasons": None if sc.dry else dict(self.stepper.remesh_reasons),
            **({} if sc.dry else self.stepper.factor_counts),
            "retries": self.retries,
            "rejections": self.rejections,
            "euler_steps_at_contacts": self.euler_steps,
            "adaptive": sc.time.adaptive,
            "dt_range": ([float(hist.dt.min()), float(hist.dt.max())] if len(hist) else None),
            "remesh_energy_ratio_max": max(ratios, default=None),
            "status": self.status,
            "stopped_by": self.stopped_by,
            "failed": self.failure,
            "warnings": list(self.warnings),
            "wall_time": {k: round(v, 6) for k, v in self.timings.items()},
        }
        if not sc.dry:
            import meshing

            st = meshing.mesh_stats(self.mesh)
            out["mesh"] = {
                "kind": getattr(getattr(self.stepper.meshed, "recipe", None), "kind",
                                sc.mesh.kind),  # what "auto" chose
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

    def _finish(self, log, summary):
        """Complete ``history.csv`` (the live file, synced) and write ``summary.json``."""
        if self.output_dir is None:
            return []
        d = self.output_dir
        if log is not None:
            log.close()
        else:  # the log could not be opened: the whole table at once
            self.history.to_csv(d / "history.csv")
        text = json.dumps(summary, indent=2)
        atomic_write(d / "summary.json", lambda tmp: Path(tmp).write_text(text))
        return [d / "history.csv", d / "summary.json"]
