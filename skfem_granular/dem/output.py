"""Output: particle outlines as VTU polygons (meshio), .pvd series, history tables."""

from __future__ import annotations

import csv
import os
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

__all__ = ["History", "VTUSeries", "write_outlines_vtu", "write_pvd"]

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
    for kind, lines in (("shadow", system.shadow_outlines()), ("core", system.core_outlines())):
        for k, o in enumerate(lines):
            outlines.append((o, k, KIND[kind]))
    for w, o in enumerate(system.wall_outlines()):
        outlines.append((o, -1 - w, KIND["wall"]))
    v = system.particles.v
    pts, blocks, offset = [], {}, 0
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
    cells, data = [], {"particle": [], "kind": [], "vx": [], "vy": [], "omega": []}
    for n in sorted(blocks):
        b = blocks[n]
        cells.append(("polygon" if n > 3 else "triangle", np.array(b["conn"])))
        owner = np.array(b["owner"])
        data["particle"].append(owner)
        data["kind"].append(np.array(b["kind"]))
        part = owner >= 0
        idx = np.where(part, owner, 0)
        for name, row in (("vx", 0), ("vy", 1), ("omega", 2)):
            data[name].append(np.where(part, v[row, idx] if v.shape[1] else 0.0, 0.0))
    meshio.Mesh(points, cells, cell_data=data).write(str(path))


def write_pvd(path, entries) -> None:
    """Write a ParaView collection ``path`` listing ``(time, filename)`` entries.

    meshio has no writer for this tiny XML index, so it is written here.
    """
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
             "  <Collection>"]
    for t, name in entries:
        lines.append(f'    <DataSet timestep="{float(t):.17g}" group="" part="0" '
                     f"file={quoteattr(str(name))}/>")
    lines += ["  </Collection>", "</VTKFile>", ""]
    Path(path).write_text("\n".join(lines))


class VTUSeries:
    """A series of VTU outline files plus a ``.pvd`` index.

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
        self.entries = []

    def write(self, system) -> Path:
        """Write the current outlines as the next frame and update the index."""
        fname = f"{self.name}_{len(self.entries):05d}.vtu"
        write_outlines_vtu(self.directory / fname, system)
        self.entries.append((system.t, fname))
        write_pvd(self.directory / f"{self.name}.pvd", self.entries)
        return self.directory / fname

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


class History:
    """Time history of a :class:`~skfem_granular.dem.DEMSystem`.

    Call :meth:`record` after steps; read the arrays ``t`` ``(T,)``,
    ``positions``/``velocities`` ``(T, 2, N)``, ``angles``/``angular_velocities``/
    ``contacts`` ``(T, N)``, ``kinetic_energy``/``elastic_energy`` ``(T,)``.
    """

    FIELDS = ("t", "positions", "angles", "velocities", "angular_velocities", "contacts",
              "kinetic_energy", "elastic_energy")

    def __init__(self):
        self._rows = {k: [] for k in self.FIELDS}

    def record(self, system) -> None:
        """Append the current state of ``system``."""
        r = self._rows
        r["t"].append(system.t)
        r["positions"].append(system.positions.copy())
        r["angles"].append(system.angles.copy())
        r["velocities"].append(system.velocities.copy())
        r["angular_velocities"].append(system.angular_velocities.copy())
        r["contacts"].append(system.contact_count())
        r["kinetic_energy"].append(system.kinetic_energy())
        r["elastic_energy"].append(system.elastic_energy())

    def __len__(self) -> int:
        return len(self._rows["t"])

    def __getattr__(self, name):
        if name in History.FIELDS:
            return np.array(self._rows[name])
        raise AttributeError(name)

    def to_csv(self, path) -> None:
        """Write one row per (time, particle): ``t, particle, x, y, angle, vx, vy,
        omega, contacts, kinetic_energy, elastic_energy`` (energies are totals)."""
        os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["t", "particle", "x", "y", "angle", "vx", "vy", "omega",
                        "contacts", "kinetic_energy", "elastic_energy"])
            r = self._rows
            for s, t in enumerate(r["t"]):
                X, V = r["positions"][s], r["velocities"][s]
                for k in range(X.shape[1]):
                    w.writerow([repr(float(t)), k, repr(float(X[0, k])), repr(float(X[1, k])),
                                repr(float(r["angles"][s][k])), repr(float(V[0, k])),
                                repr(float(V[1, k])),
                                repr(float(r["angular_velocities"][s][k])),
                                int(r["contacts"][s][k]), repr(r["kinetic_energy"][s]),
                                repr(r["elastic_energy"][s])])
