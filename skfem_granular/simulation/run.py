"""Simulation: builds what a scene calls for, drives its stepper, records what it yields.

A scene with fluid gets a :class:`~skfem_granular.coupled.CoupledStepper`
(mesh, coupling, DEM, remeshing); a dry scene a
:class:`~skfem_granular.simulation.dry.DryStepper` (the DEM alone, no mesh).
:meth:`Simulation.evolve` is the stepper's generator with the recording added:
after every accepted step it appends the history row, writes the VTU frames
every ``vtu_every`` steps and a checkpoint every ``checkpoint_every`` steps.
``history.csv`` grows as the run goes: rows are appended and synced to the
disk with every frame, every checkpoint, at least every
:data:`~skfem_granular.simulation.recorder.FLUSH_SECONDS` of wall time and
when the loop ends, so a run killed even with SIGKILL leaves a readable
history up to its last flush. When the loop ends, however it ends
(completed, failed, broken off, or stopped by SIGINT/SIGTERM), the history
is complete and ``summary.json`` is written with the run's ``status``.
:meth:`Simulation.run` drives that generator to the end.

A checkpoint (:mod:`~skfem_granular.simulation.checkpoint`) follows the rows
of ``history.csv`` instead of holding them, so its size does not grow with the
run; the one before it is kept as ``checkpoint.prev.npz``.

SIGINT and SIGTERM (in the main thread) stop a run at the end of the current
step: the step is recorded, a checkpoint is written (so the run can be
resumed, bit for bit), the history and the summary are written, and the
generator ends as if the run had reached its end (``summary["status"] ==
"stopped"``, ``summary["stopped_by"] == "SIGTERM"``). A second signal stops
the run at once (:mod:`~skfem_granular.signals`): the history of
the accepted steps and the summary are written (``summary["stopped_at_once"]``),
the last checkpoint stays. The previous handlers are restored when the loop ends.

The output folder belongs to the run (:mod:`~skfem_granular.simulation.folder`):
a new run refuses a folder that holds another run's files unless it was made
with ``overwrite=True`` (the old files are removed when the run starts);
:meth:`Simulation.resume` continues the checkpoint's run in its folder; a lock
file refuses a second live run into the same folder.
"""

from __future__ import annotations

import math
import sys
import time
from collections import defaultdict
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from .. import timestep as ts
from ..coupled.build import build_mesh
from ..coupled.stepper import CoupledStepper, SimulationError
from ..dem import DEMSystem
from ..fluid.linsolve import FactorizationMemoryError
from ..io import History, check_writable
from ..scene import Scene
from ..signals import StopNow, StopSignals, deferred
from .budget import Budget, taylor_hood_unknowns
from .dry import DryStepper
from .effects import contacts_needed, scene_warnings
from .folder import OutputFolder
from .progress import count_step, progress_bar
from .recorder import RunOutput
from .report import summarize


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
    overwrite : bool, optional
        Replace another run's output in ``output_dir`` (its files are removed
        when the run starts). Without it, a folder holding another run's files
        is refused with a :class:`~skfem_granular.simulation.folder.FolderInUseError`
        (a ``ValueError``); continue such a run with :meth:`resume`.
    budget : Budget, optional
        Limits on steps, mesh triangles and memory, checked against estimates before
        the mesh is built (:mod:`~skfem_granular.simulation.budget`; default
        ``Budget()``); a run beyond them raises a ``BudgetError`` (a ``ValueError``).
    terms : UserTerms, optional
        scikit-fem forms added to the fluid's momentum and continuity equations
        (:class:`~skfem_granular.fluid.UserTerms`, docs: user forms); a checkpoint does
        not hold them: give them again to :meth:`resume`.
    assembly : {"compiled", "scikit-fem"}
        How the fluid's built-in blocks are assembled: the compiled kernels (default)
        or scikit-fem's ``asm`` of :mod:`skfem_granular.fluid.forms` (the same run to
        round-off, slower; :class:`~skfem_granular.fluid.TaylorHood`).

    Examples
    --------
    >>> sim = Simulation(Scene.bundled("single_particle"))   # doctest: +SKIP
    >>> for t, step in sim.evolve():                          # doctest: +SKIP
    ...     print(t, step.force[1, 0], sim.dem.velocities[1, 0])
    """

    def __init__(self, scene: Scene, output_dir=None, *, mesh=None, overwrite: bool = False,
                 budget: Budget | None = None, terms=None, assembly: str = "compiled"):
        t_set_up = time.perf_counter()
        if not isinstance(scene, Scene):
            scene = Scene.from_toml(scene)
        self.scene = scene
        budget = Budget() if budget is None else budget
        budget.check_steps(scene)
        self.timings: defaultdict[str, float] = defaultdict(float)
        out = output_dir if output_dir is not None else scene.output_dir
        self.output_dir = None if out is None else Path(out)
        self.folder = None
        self._holds_lock = False
        if self.output_dir is not None:
            check_writable(self.output_dir / "summary.json")
            self.folder = OutputFolder(self.output_dir, "overwrite" if overwrite else "new")
            self.folder.check()  # before any work: another run's output, a live lock
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
        self.failure: str | None = None
        self.status = "not started"
        self.stopped_by: str | None = None
        self.stopped_at_once = False
        self.history = History(self.dem.n)
        self.steps_done = 0
        self.result: SimulationResult | None = None
        self._resumed_frames: dict = {}
        self._resumed_from: Path | None = None  # the checkpoint file a resumed run read
        self._output: RunOutput | None = None  # while evolve() runs
        self.stepper: DryStepper | CoupledStepper
        if scene.dry:
            self.stepper = DryStepper(scene, self.dem, self.timings)
        else:
            t0 = time.perf_counter()
            if mesh is None:
                cores = self.dem.core_outlines()
                budget.check_mesh(scene, cores)
                mesh = build_mesh(scene, cores)
            budget.check_unknowns(scene, taylor_hood_unknowns(mesh.mesh))
            self.timings["meshing"] += time.perf_counter() - t0
            self.stepper = CoupledStepper(scene, self.dem, mesh,
                                          contacts_active=self.contacts_active,
                                          timings=self.timings, terms=terms,
                                          assembly=assembly)
        # the total counts the set-up too (its first mesh and blocks are phases of it)
        self.timings["total"] += time.perf_counter() - t_set_up

    @classmethod
    def resume(cls, directory, t_end: float | None = None, *,
               budget: Budget | None = None, terms=None,
               coupling: str | None = None, mesh_repair: str | None = None) -> Simulation:
        """Continue a run from the checkpoint in ``directory``.

        Parameters
        ----------
        directory : str or Path
            Output directory of a run with ``output.checkpoint_every > 0``.
        t_end : float, optional
            New end time (default: the scene's).
        budget : Budget, optional
            Limits the continued run is checked against (see :class:`Simulation`).
        terms : UserTerms, optional
            The user forms of the fluid the run was started with (not in the checkpoint).
        coupling : {"monolithic", "split"}, optional
            Continue with this coupled solver instead of the run's (``Scene.coupling``),
            for instance a many-grain run on the split solver; the state carries over, the
            new solver factorises anew.
        mesh_repair : {"auto", "flips", "none"}, optional
            Continue with this ``Scene.mesh_repair`` instead of the run's.

        Returns
        -------
        Simulation
            Ready to :meth:`run` from the checkpointed step; output continues
            in ``directory`` (``history.csv`` cut after the checkpoint's rows
            when the run starts, ``.partial-*`` left-overs of a killed run removed).
            ``t_end`` may not be before the checkpoint's time. The newest usable
            checkpoint is taken: ``checkpoint.npz``, or ``checkpoint.prev.npz`` when
            that one cannot be used (one line on stderr and in the summary's
            ``warnings`` saying why).

        Raises
        ------
        ValueError
            One line naming the field, for a missing, foreign, older (pickle: not read) or
            inconsistent checkpoint (:func:`~skfem_granular.simulation.checkpoint.load`),
            a ``history.csv`` without the checkpoint's rows (shorter, or changed), a
            ``t_end`` before the checkpoint's time, or a folder a live run holds.
        """
        from . import checkpoint

        folder = OutputFolder(directory, "resume")
        folder.check()
        data = checkpoint.load(directory)
        scene = data["scene"]
        t_ck = float(data["history"][-1]["t"]) if data["history"] else 0.0
        if t_end is not None:
            if not t_end >= t_ck * (1.0 - 1e-12):
                raise ValueError(f"t_end (--t-end) = {t_end!r}: must be >= {t_ck!r}, the time "
                                 "of the checkpoint the run continues from (start a new run "
                                 "with overwrite to end earlier)")
            scene = replace(scene, time=replace(scene.time, t_end=t_end))
        saved = data["stepper"]
        if isinstance(saved, dict) and "mesh_centers" in saved:  # a coupled run's
            saved = CoupledStepper.with_later_entries(saved)
        if coupling is not None and coupling != scene.coupling:
            if coupling not in ("monolithic", "split") or scene.coupling == "partitioned":
                raise ValueError(f"coupling = {coupling!r}: a run on the "
                                 f"{scene.coupling!r} coupling continues on 'monolithic' or "
                                 "'split' (the partitioned scheme's mesh does not move)")
            scene = replace(scene, coupling=coupling)
            saved = {**saved, "factor_a0": None}  # the other solver's factorisation
        if mesh_repair is not None:
            scene = replace(scene, mesh_repair=mesh_repair)  # validated by the Scene
        sim = cls(replace(scene, output_dir=None), mesh=saved.get("mesh"),  # no folder check
                  budget=budget, terms=terms)
        sim.scene, sim.output_dir, sim.folder = scene, Path(directory), folder
        # the entries this version's stepper and DEM hand over, no more and no fewer
        where = f"checkpoint {str(data['path'])!r}"
        checkpoint.check_entries(data["dem"], sim.dem.save_state(), "dem", where)
        checkpoint.check_entries(saved, sim.stepper.checkpoint_state(), "stepper", where)
        sim.dem.restore_state(data["dem"])
        if isinstance(sim.stepper, DryStepper):
            sim.stepper.steps_taken = saved["steps_taken"]
        else:
            t0 = time.perf_counter()
            sim.stepper = CoupledStepper.from_checkpoint_state(
                scene, sim.dem, saved, contacts_active=sim.contacts_active, timings=sim.timings,
                terms=terms)
            sim.timings["total"] += time.perf_counter() - t0  # set-up too
        sim.history.adopt(data["history"], Path(directory) / checkpoint.HISTORY_FILENAME)
        sim._continue_clock()
        sim.steps_done = data["k"]
        sim._resumed_frames = data["frames"]
        sim._resumed_from = data["path"]
        if data["warning"]:
            sim.warnings.append(data["warning"])
            print(f"skfem-granular: warning: {data['warning']}", file=sys.stderr)
        return sim

    def _continue_clock(self) -> None:
        """A run resumed past the end of the run it continues: that run's last row reported
        ``t_end`` exactly (:func:`~skfem_granular.timestep.end_time`), its clock is the sum
        of the steps; the row gets the clock's time back, as the run that never stopped
        there has it (the rows stay bit for bit those of one uninterrupted run)."""
        rows, st = self.history.rows, self.stepper
        if not rows or isinstance(st, DryStepper):
            return
        clock, dt = st.state.t, self.scene.time.dt
        last = rows[-1]["t"]
        if (last != clock and abs(last - clock) <= ts.END_RTOL * dt
                and not ts.reached(clock, self.scene.time.t_end, dt)):
            rows[-1] = dict(rows[-1], t=clock)

    # ------------------------------------------------------------------ views
    def __repr__(self) -> str:
        kind = "dry" if self.scene.dry else repr(self.stepper).split("(", 1)[1].rstrip(")")
        out = "no output" if self.output_dir is None else f"output {str(self.output_dir)!r}"
        return (f"Simulation({self.scene.name!r}, t_end={self.scene.time.t_end:g} s: {kind}; "
                f"{out})")

    def _coupled(self, name) -> CoupledStepper:
        if not isinstance(self.stepper, CoupledStepper):  # a dry scene's
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
        return 0 if self.scene.dry else self._coupled("remeshes").remeshes

    @property
    def retries(self) -> int:
        """Step halvings after corrector failures."""
        return 0 if self.scene.dry else self._coupled("retries").retries

    @property
    def rejections(self) -> int:
        """Steps rejected by the error control (adaptive runs)."""
        return 0 if self.scene.dry else self._coupled("rejections").rejections

    @property
    def euler_steps(self) -> int:
        """Backward-Euler steps taken because of contacts."""
        return 0 if self.scene.dry else self._coupled("euler_steps").euler_steps

    @property
    def remesh_energy_ratios(self) -> list:
        """Fluid kinetic energy after / before each transfer onto a new mesh."""
        return [] if self.scene.dry else self._coupled("remesh_energy_ratios").remesh_energy_ratios

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
            When a step does not converge (the history and the last good state are
            written first) or the output cannot be written (a full disk; the files
            written before stay intact).
        FolderInUseError
            When the first step is asked for and the output folder holds another run's
            files or a live run's lock (nothing is written).
        """
        t_start = time.perf_counter()
        try:
            self._take_lock()
            bar = self._progress_bar(progress)
            self.status, self.stopped_by, self.stopped_at_once = "running", None, False
            signals = StopSignals()
            out = RunOutput(self, signals, self._resumed_frames, self._resumed_from)
            self._output = out
            with signals, threadpool_limits(limits=1, user_api="blas"):
                try:
                    # the folder's first files and the start checkpoint together: a second
                    # signal waits for both, so the folder is untouched or resumable
                    with deferred():
                        out.open()
                        if self.steps_done == 0 and self._resumed_from is None:
                            out.frame(0.0)
                            if self.scene.checkpoint_every:
                                out.checkpoint()
                    for t, step in self.stepper.evolve():
                        checkpointed = self._after_step(t, step, out)
                        count_step(bar)
                        yield t, step
                        if signals.stopped_by is not None:  # SIGINT/SIGTERM during the step
                            self.stopped_by = signals.stopped_by
                            if not checkpointed:
                                out.checkpoint()
                            self.status = "stopped"
                            break
                    else:
                        self.status = "completed"
                except StopNow as exc:  # a second signal: at once, the step not finished
                    self._stopped_at_once(signals, exc)
                except GeneratorExit:
                    if signals.at_once:  # the second signal came in the caller's loop
                        self._stopped_at_once(signals, StopNow(signals.stopped_by))
                    else:
                        self.status = "closed"  # the caller broke off the loop
                    raise
                except (SimulationError, FloatingPointError, OSError,
                        FactorizationMemoryError) as exc:
                    self._failed(exc, out)
                except BaseException as exc:  # KeyboardInterrupt, errors
                    self.status = "failed"
                    self.failure = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
                    raise
                finally:
                    with signals.critical(raise_pending=False):
                        bar.close()
                        self._wrap_up(out, t_start)
        finally:
            self._output = None
            if self._holds_lock and self.folder is not None:
                self.folder.release()
                self._holds_lock = False

    def _take_lock(self) -> None:
        """Take the output folder's lock (refused: another run's output or a live lock);
        a deferred zone, so a signal cannot come between taking it and knowing it ours."""
        with deferred():
            if self.folder is not None:
                self.folder.acquire()
                self._holds_lock = True

    def _progress_bar(self, progress):
        """The bar of the steps this process has left to take."""
        sc = self.scene
        n_steps = max(1, int(math.ceil(sc.time.t_end / sc.time.dt - 1e-9)))
        return progress_bar(sc.name, max(0, n_steps - self.steps_done), progress)

    def _after_step(self, t, step, out: RunOutput) -> bool:
        """Record the accepted step: history row, frame, checkpoint, flush; True if checkpointed."""
        self.steps_done += 1
        out.record(step)
        if out.frame_due(self.steps_done, t):
            out.frame(t)
            out.flush()
        every = self.scene.checkpoint_every
        if every and self.output_dir is not None and self.steps_done % every == 0:
            out.checkpoint()
            return True
        out.flush_due()
        return False

    def _stopped_at_once(self, signals: StopSignals, exc: StopNow) -> None:
        self.status, self.stopped_at_once = "stopped", True
        self.stopped_by = signals.stopped_by or exc.name

    def _failed(self, exc, out: RunOutput):
        """A step that failed, or output that could not be written: one line, the rest kept."""
        self.status = "failed"
        if isinstance(exc, OSError):
            what = exc.strerror or type(exc).__name__
            self.failure = (f"writing the output failed: {what}"
                            + (f": {exc.filename}" if exc.filename else ""))
            raise SimulationError(f"{self.failure}; the files written before are intact"
                                  ) from exc
        self.failure = str(exc)
        if isinstance(self.stepper, CoupledStepper):
            try:
                out.frame(self.stepper.state.t)
            except OSError:
                pass
        where = ("no output folder: the last good state is in sim.last_good"
                 if self.output_dir is None
                 else f"history and last good state written to {self.output_dir}")
        raise SimulationError(f"{exc}; {where}") from exc

    def _wrap_up(self, out: RunOutput, t_start):
        """Timings, summary, the history completed and ``summary.json``: :attr:`result` set."""
        self.stepper.collect_timings()
        self.timings["total"] += time.perf_counter() - t_start
        summary = self.summary(self.history)
        try:
            files = out.finish(summary)
        except OSError as exc:
            files = []
            if self.status != "failed":  # nothing else in flight: this is the failure
                self.status, self.failure = "failed", f"writing the output failed: {exc}"
                self.result = SimulationResult(self.history, summary, self.output_dir, files)
                raise SimulationError(f"writing the output failed: {exc.strerror or exc}"
                                      + (f": {exc.filename}" if exc.filename else "")) from exc
        self.result = SimulationResult(self.history, summary, self.output_dir, files)

    def run(self, progress: bool | None = None) -> SimulationResult:
        """Run to ``scene.time.t_end``; returns a :class:`SimulationResult`.

        Parameters
        ----------
        progress : bool, optional
            Show a tqdm progress bar (default: when the run has > 50 steps).
        """
        steps = self.evolve(progress)
        try:
            for _ in steps:
                pass
        except StopNow:  # a second signal between two steps: the generator writes, then ends
            steps.close()
            if self.result is None:  # before the loop opened: nothing run, nothing written
                raise
        assert self.result is not None  # the generator writes it however its loop ends
        return self.result

    def fluid_energy(self) -> float:
        """Kinetic energy ``rho u.M u / 2`` of the fluid now (J per unit depth)."""
        return self._coupled("fluid").fluid_energy()

    # ------------------------------------------------------------------ report
    def summary(self, hist: History) -> dict:
        """Run summary: effects, mesh, final state, wall times, warnings.

        ``status`` is ``"completed"``, ``"stopped"`` (by the signal named in
        ``stopped_by``; ``stopped_at_once`` when a second one ended the step),
        ``"failed"`` (the reason in ``failed``), ``"closed"`` (the caller broke off
        :meth:`evolve`'s loop) or ``"running"``.
        """
        return summarize(self, hist)

