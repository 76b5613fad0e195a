"""What a run writes as it goes: the live history, the VTU frames, checkpoints, the summary.

:class:`RunOutput` is the output side of :meth:`Simulation.evolve
<skfem_granular.simulation.Simulation.evolve>`: the loop only calls it. With no
output folder every call does nothing. Each file is written inside the
simulation's :meth:`StopSignals.critical
<skfem_granular.signals.StopSignals.critical>` section, so a second
signal never tears one.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from ..dem.output import write_outlines_vtu
from ..io import CSVLog, PVDSeries, atomic_write

#: The history file is synced at least this often (wall seconds) besides frames and checkpoints.
FLUSH_SECONDS = 10.0


class RunOutput:
    """History, frames, checkpoints and summary of one :class:`Simulation` run.

    Parameters
    ----------
    sim : Simulation
        The run (its ``output_dir``, ``history``, ``dem``, ``stepper``, ``timings``).
    signals : StopSignals
        Whose critical sections guard the writes.
    frames : dict, optional
        ``{series: [(t, file), ...]}``: the frames a resumed run wrote before.
    resumed_from : Path, optional
        The checkpoint file a resumed run was read from.
    """

    def __init__(self, sim, signals, frames=None, resumed_from=None):
        self.sim = sim
        self.frames = frames or {}
        self.resumed_from = resumed_from
        self.signals = signals
        self.dir = sim.output_dir
        self.series = None
        self.log = None
        self._flushed = time.monotonic()

    def open(self) -> None:
        """The PVD series (with a resumed run's frames) and the live ``history.csv``."""
        if self.dir is None:
            return
        sim = self.sim
        self.series = {"flow": None if sim.scene.dry else PVDSeries(self.dir / "flow.pvd"),
                       "particles": PVDSeries(self.dir / "particles.pvd")}
        for name, frames in self.frames.items():
            if self.series.get(name) is not None:
                self.series[name].frames = list(frames)
        # header and the rows so far (a resumed run's), then appends
        self.log = CSVLog(sim.history, self.dir / "history.csv")
        self._flushed = time.monotonic()
        if self.resumed_from is not None:  # resumed from the previous checkpoint: the newest
            from . import checkpoint

            checkpoint.promote(self.dir, self.resumed_from)

    def record(self, step) -> None:
        """Append the history row of an accepted step (a ``StepReport``)."""
        dem = self.sim.dem
        acc = step.acceleration
        self.sim.history.append(
            step.t, step.dt, step.iterations, fluid_energy=step.fluid_energy,
            error=step.error, x=dem.positions[0], y=dem.positions[1], angle=dem.angles,
            vx=dem.velocities[0], vy=dem.velocities[1], omega=dem.angular_velocities,
            ax=acc[0], ay=acc[1], Fx=step.force[0], Fy=step.force[1], torque=step.torque,
            contacts=dem.contact_count())

    def frame_due(self, k: int, t: float) -> bool:
        """Whether step ``k`` (at time ``t``) writes a frame: every ``vtu_every``, and the last."""
        sc = self.sim.scene
        last = t >= sc.time.t_end - 1e-9 * sc.time.dt
        return last or (sc.vtu_every > 0 and k % sc.vtu_every == 0)

    def _timed(self, write) -> None:
        t0 = time.perf_counter()
        with self.signals.critical():
            write()
        self.sim.timings["output"] += time.perf_counter() - t0

    def flush(self) -> None:
        """Sync the history file."""
        if self.log is not None:
            self._timed(self.log.flush)
            self._flushed = time.monotonic()

    def flush_due(self) -> None:
        """Sync the history file if :data:`FLUSH_SECONDS` passed since the last sync."""
        if time.monotonic() - self._flushed > FLUSH_SECONDS:
            self.flush()

    def frame(self, t: float) -> None:
        """The VTU frames of the particles (and the flow) at time ``t``."""
        if self.series is None:
            return
        sim = self.sim
        dem, flow = sim.dem, self.series["flow"]

        def write():
            self.series["particles"].write(t, lambda f: write_outlines_vtu(f, dem))
            if flow is not None:
                flow.write(t, sim.stepper.flow().save)

        self._timed(write)

    def checkpoint(self) -> None:
        """History synced first, then the checkpoint (which follows the file's rows)."""
        if self.dir is None:
            return
        from . import checkpoint

        self.flush()
        self._timed(lambda: checkpoint.save(self.sim, self.sim.steps_done, self.series))

    def finish(self, summary: dict) -> list:
        """Complete ``history.csv`` (the live file, synced) and write ``summary.json``."""
        if self.dir is None:
            return []
        if self.log is not None:
            self.log.close()
        else:  # the log could not be opened: the whole table at once
            self.sim.history.to_csv(self.dir / "history.csv")
        text = json.dumps(summary, indent=2)
        atomic_write(self.dir / "summary.json", lambda tmp: Path(tmp).write_text(text))
        return [self.dir / "history.csv", self.dir / "summary.json"]
