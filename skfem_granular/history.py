"""Time-series record of a run: arrays in memory, CSV on disk."""

from __future__ import annotations

import numpy as np

from .io import atomic_write

#: Per-particle columns: name -> how to read it from a record.
#: Columns of one value per step.
STEP_COLUMNS = ("t", "dt", "iterations", "fluid_energy", "error")

PARTICLE_COLUMNS = (
    "x",
    "y",
    "angle",
    "vx",
    "vy",
    "omega",
    "ax",
    "ay",
    "Fx",
    "Fy",
    "torque",
    "contacts",
)


class History:
    """Rows appended once per step; columns as arrays.

    Attributes: ``t``, ``dt``, ``iterations``, ``fluid_energy``, ``error``
    (the local error estimate of adaptive runs, NaN otherwise) (N,) and
    for each particle column a ``(N, K)`` array: positions ``x``, ``y``,
    ``angle``, velocities ``vx``, ``vy``, ``omega``, accelerations ``ax``,
    ``ay``, fluid forces ``Fx``, ``Fy``, ``torque`` and contact counts.
    """

    def __init__(self, n_particles: int):
        self.K = n_particles
        self.rows = []

    def append(self, t: float, dt: float, iterations: int, fluid_energy: float = float("nan"),
               error: float = float("nan"), **particle):
        """Add one step; ``particle`` holds ``(K,)`` arrays named as :data:`PARTICLE_COLUMNS`.

        ``fluid_energy`` is the fluid's kinetic energy ``rho u.M u / 2`` (J per unit depth).
        """
        row = {"t": t, "dt": dt, "iterations": iterations, "fluid_energy": float(fluid_energy),
               "error": float(error)}
        for c in PARTICLE_COLUMNS:
            row[c] = np.array(particle.get(c, np.zeros(self.K)), dtype=float).reshape(self.K)
        self.rows.append(row)

    def __len__(self):
        return len(self.rows)

    def __getattr__(self, name):
        if name in STEP_COLUMNS:
            return np.array([r.get(name, np.nan) for r in self.rows])
        if name in PARTICLE_COLUMNS:
            return np.array([r[name] for r in self.rows]).reshape(len(self.rows), self.K)
        raise AttributeError(name)

    def to_csv(self, path) -> None:
        """Write the table (one column per quantity and particle) atomically."""
        head = list(STEP_COLUMNS) + [
            f"{c}_{k}" for k in range(self.K) for c in PARTICLE_COLUMNS
        ]
        data = (
            np.column_stack(
                [getattr(self, c) for c in STEP_COLUMNS]
                + [getattr(self, c)[:, k] for k in range(self.K) for c in PARTICLE_COLUMNS]
            )
            if self.rows
            else np.zeros((0, len(head)))
        )

        def write(tmp):
            np.savetxt(tmp, data, delimiter=",", header=",".join(head), comments="", fmt="%.10g")

        atomic_write(path, write)
