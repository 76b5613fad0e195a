"""Output: particle outlines as VTU polygons (meshio), .pvd series, history tables."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..io.pvd import PVDSeries
from ..io.table import Table

__all__ = ["History", "VTUSeries", "write_outlines_vtu"]

#: cell-data code of the outline kinds in the VTU files
KIND = {"shadow": 0, "core": 1, "wall": 2}


def write_outlines_vtu(path, system) -> None:
    """Write shadow and core outlines of all particles and the walls to ``path``.

    One VTK polygon cell per outline (grouped by vertex count), with cell
    data ``particle`` (index, ``-1`` for walls, ``-1 - w`` for wall ``w``
    in ``body``), ``kind`` (0 shadow, 1 core, 2 wall), ``vx``, ``vy``,
    ``omega``.
    """
    import meshio

    outlines = []
    for label, lines in (("shadow", system.shadow_outlines()), ("core", system.core_outlines())):
        for k, o in enumerate(lines):
            outlines.append((o, k, KIND[label]))
    for w, o in enumerate(system.wall_outlines()):
        outlines.append((o, -1 - w, KIND["wall"]))
    v = system.particles.v
    pts: list[np.ndarray] = []
    blocks: dict[int, dict[str, list]] = {}
    offset = 0
    for o, owner, kind in outlines:
        n = o.shape[1]
        pts.append(o.T)
        b = blocks.setdefault(n, {"conn": [], "owner": [], "kind": []})
        b["conn"].append(np.arange(offset, offset + n))
        b["owner"].append(owner)
        b["kind"].append(kind)
        offset += n
    points = np.zeros((offset, 3))
    if pts:
        points[:, :2] = np.concatenate(pts, axis=0)
    cells: list[tuple[str, np.ndarray]] = []
    data: dict[str, list[np.ndarray]] = {"particle": [], "kind": [], "vx": [], "vy": [],
                                         "omega": []}
    for n in sorted(blocks):
        b = blocks[n]
        cells.append(("polygon" if n > 3 else "triangle", np.array(b["conn"])))
        owners = np.array(b["owner"])
        data["particle"].append(owners)
        data["kind"].append(np.array(b["kind"]))
        part = owners >= 0
        idx = np.where(part, owners, 0)
        for name, row in (("vx", 0), ("vy", 1), ("omega", 2)):
            data[name].append(np.where(part, v[row, idx] if v.shape[1] else 0.0, 0.0))
    meshio.Mesh(points, cells, cell_data=data).write(str(path))


class VTUSeries:
    """A series of VTU outline files plus a ``.pvd`` index (atomic, as every series here).

    Parameters
    ----------
    directory
        Output folder (created).
    name
        File stem: frames ``name_00000.vtu`` ..., index ``name.pvd``.

    Examples
    --------
    >>> with VTUSeries("out/pile") as series:  # doctest: +SKIP
    ...     for _ in range(10):
    ...         system.advance(1e-3)
    ...         series.write(system)
    """

    def __init__(self, directory, name: str = "dem"):
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self.name = name
        self._series = PVDSeries(self.directory / f"{name}.pvd")

    @property
    def entries(self) -> list[tuple[float, str]]:
        """``(time, file name)`` of the frames written."""
        return self._series.frames

    def write(self, system) -> Path:
        """Write the current outlines as the next frame and update the index."""
        return self._series.write(system.t, lambda f: write_outlines_vtu(f, system))

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


class History(Table):
    """Time history of a :class:`~skfem_granular.dem.DEMSystem`.

    Call :meth:`record` after steps; read the arrays ``t`` ``(T,)``,
    ``positions``/``velocities`` ``(T, 2, N)``, ``angles``/``angular_velocities``/
    ``contacts`` ``(T, N)``, ``kinetic_energy``/``elastic_energy`` ``(T,)``.
    """

    STEP_COLUMNS = ("t", "kinetic_energy", "elastic_energy")
    PARTICLE_COLUMNS = ("x", "y", "angle", "vx", "vy", "omega", "contacts")

    def __init__(self):
        super().__init__(0)

    def record(self, system) -> None:
        """Append the current state of ``system``."""
        self.K = system.n
        self.add_row(t=system.t, kinetic_energy=system.kinetic_energy(),
                     elastic_energy=system.elastic_energy(), x=system.positions[0],
                     y=system.positions[1], angle=system.angles, vx=system.velocities[0],
                     vy=system.velocities[1], omega=system.angular_velocities,
                     contacts=system.contact_count())

    @property
    def positions(self) -> np.ndarray:
        return np.stack([self.x, self.y], axis=1)

    @property
    def velocities(self) -> np.ndarray:
        return np.stack([self.vx, self.vy], axis=1)

    @property
    def angles(self) -> np.ndarray:
        return self.angle

    @property
    def angular_velocities(self) -> np.ndarray:
        return self.omega

    def to_csv(self, path, layout: str = "long") -> None:
        """Write one row per (time, particle): ``t, particle, x, y, angle, vx, vy,
        omega, contacts, kinetic_energy, elastic_energy`` (energies are totals)."""
        os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
        super().to_csv(path, layout)
