"""Time-series tables: one row per step, columns as arrays, CSV on disk (atomic).

:class:`Table` is the one implementation; :class:`History` is the table of a
coupled run (what :class:`~skfem_granular.simulation.Simulation` records), and
:class:`skfem_granular.dem.History` the table of a dry DEM run.
"""

from __future__ import annotations

import numpy as np

from .files import atomic_write


class Table:
    """Rows appended once per step: per-step values and per-particle ``(K,)`` arrays.

    Subclasses name their columns in :attr:`STEP_COLUMNS` and
    :attr:`PARTICLE_COLUMNS`. Columns read as arrays: a step column ``(T,)``, a
    particle column ``(T, K)``.

    Parameters
    ----------
    n_particles : int
        ``K``, the length of every per-particle value.
    """

    STEP_COLUMNS: tuple[str, ...] = ()
    PARTICLE_COLUMNS: tuple[str, ...] = ()

    def __init__(self, n_particles: int):
        self.K = int(n_particles)
        self.rows = []

    def add_row(self, **values) -> None:
        """Append one step; missing step values are NaN, missing particle values 0."""
        row = {c: values.get(c, np.nan) for c in self.STEP_COLUMNS}
        for c in self.PARTICLE_COLUMNS:
            row[c] = np.array(values.get(c, np.zeros(self.K)), dtype=float).reshape(self.K)
        self.rows.append(row)

    def __len__(self):
        return len(self.rows)

    def __getattr__(self, name):
        if name in type(self).STEP_COLUMNS:
            return np.array([r.get(name, np.nan) for r in self.rows])
        if name in type(self).PARTICLE_COLUMNS:
            return np.array([r[name] for r in self.rows]).reshape(len(self.rows), self.K)
        raise AttributeError(name)

    def to_csv(self, path, layout: str = "wide") -> None:
        """Write the table atomically, every number to full precision (``%.17g``).

        Parameters
        ----------
        path : str or Path
        layout : {"wide", "long"}
            ``"wide"``: one row per step, one column per quantity and particle
            (``x_0``, ``y_0``, ...); ``"long"``: one row per step and particle, the
            first step column and ``particle`` first, then the particle columns,
            then the other step columns.
        """
        T, K = len(self.rows), self.K
        steps, parts = self.STEP_COLUMNS, self.PARTICLE_COLUMNS
        if layout == "wide":
            head = list(steps) + [f"{c}_{k}" for k in range(K) for c in parts]
            cols = ([getattr(self, c) for c in steps]
                    + [getattr(self, c)[:, k] for k in range(K) for c in parts])
        elif layout == "long":
            first, rest = steps[:1], steps[1:]
            head = list(first) + ["particle"] + list(parts) + list(rest)
            cols = ([np.repeat(getattr(self, c), K) for c in first]
                    + [np.tile(np.arange(K), T)]
                    + [getattr(self, c).ravel() for c in parts]
                    + [np.repeat(getattr(self, c), K) for c in rest])
        else:
            raise ValueError(f"layout = {layout!r}: must be 'wide' or 'long'")
        data = np.column_stack(cols) if T else np.zeros((0, len(head)))

        def write(tmp):
            np.savetxt(tmp, data, delimiter=",", header=",".join(head), comments="", fmt="%.17g")

        atomic_write(path, write)


class History(Table):
    """The per-step table of a coupled (or dry) run.

    Attributes: ``t``, ``dt``, ``iterations``, ``fluid_energy``, ``error``
    (the local error estimate of adaptive runs, NaN otherwise) ``(N,)`` and for
    each particle column a ``(N, K)`` array: positions ``x``, ``y``, ``angle``,
    velocities ``vx``, ``vy``, ``omega``, accelerations ``ax``, ``ay``, fluid
    forces ``Fx``, ``Fy``, ``torque`` and contact counts.
    """

    STEP_COLUMNS = ("t", "dt", "iterations", "fluid_energy", "error")
    PARTICLE_COLUMNS = ("x", "y", "angle", "vx", "vy", "omega", "ax", "ay", "Fx", "Fy",
                        "torque", "contacts")

    def append(self, t: float, dt: float, iterations: int, fluid_energy: float = float("nan"),
               error: float = float("nan"), **particle):
        """Add one step; ``particle`` holds ``(K,)`` arrays named as :attr:`PARTICLE_COLUMNS`.

        ``fluid_energy`` is the fluid's kinetic energy ``rho u.M u / 2`` (J per unit depth).
        """
        self.add_row(t=t, dt=dt, iterations=iterations, fluid_energy=float(fluid_energy),
                     error=float(error), **particle)
