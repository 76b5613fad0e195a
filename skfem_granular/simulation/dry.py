"""A dry scene's stepper: the DEM alone, in fixed steps, with the coupled stepper's interface."""

from __future__ import annotations

import math
import time

import numpy as np

from ..coupled.state import StepReport


class DryStepper:
    """Advances a :class:`~skfem_granular.dem.DEMSystem` with no fluid.

    Parameters
    ----------
    scene : Scene
        A dry scene (``scene.dry``); steps of ``scene.time.dt``.
    dem : DEMSystem
        The particles (their one owner).
    timings : dict, optional
        ``"dem"`` wall time is added to it.
    """

    def __init__(self, scene, dem, timings=None):
        self.scene = scene
        self.dem = dem
        self.timings = {} if timings is None else timings
        self.timings.setdefault("dem", 0.0)
        self.steps_taken = 0

    def evolve(self, t_end: float | None = None):
        """Advance to ``t_end`` (default ``scene.time.t_end``); yields ``(t, StepReport)``."""
        dt = self.scene.time.dt
        t_end = self.scene.time.t_end if t_end is None else float(t_end)
        n_steps = max(1, int(math.ceil(t_end / dt - 1e-9)))
        dem = self.dem
        zeros = np.zeros(dem.n)
        for _ in range(self.steps_taken, n_steps):
            v_old = dem.particles.v.copy()
            t0 = time.perf_counter()
            dem.advance(dt)
            self.timings["dem"] += time.perf_counter() - t0
            self.steps_taken += 1
            yield dem.t, StepReport(t=dem.t, dt=dt, iterations=0, force=np.zeros((2, dem.n)),
                                    torque=zeros, acceleration=(dem.particles.v - v_old) / dt)

    def checkpoint_state(self) -> dict:
        """The step count."""
        return {"steps_taken": self.steps_taken}

    def forget_caches(self) -> None:
        """The DEM forgets its neighbour list, as a resumed run's does."""
        self.dem.neighbours.invalidate()

    def collect_timings(self) -> dict:
        return self.timings
