"""A packing at rest: grain outlines, how it was made, what was measured; saved as plain data.

The file is a numpy ``.npz`` archive read without pickle: ``vertices`` ``(N, k, 2)``
(outlines padded by repeating their first vertex), ``counts`` ``(N,)`` and ``meta``,
a JSON string with the scalar fields of :class:`Packing`.
"""

from __future__ import annotations

import json
from dataclasses import MISSING, asdict, dataclass, field, fields
from pathlib import Path

import numpy as np

from ..dem.particles import pad_outlines
from ..io.files import atomic_write

__all__ = ["Packing", "load_packing"]


@dataclass(frozen=True)
class Packing:
    """A column of grains at rest against the walls of its box ``[0, width] x [0, ...]``.

    Attributes
    ----------
    outlines : tuple of (2, k) arrays
        World shadow outlines (counter-clockwise) of the grains at rest.
    density : float
        Grain density (kg/m^3).
    width : float
        ``L0``: the column's width, from the left wall (x = 0) to the gate.
    height : float
        ``H0``: the column's height (mean of the highest grain point over strips of
        width ``d_max``).
    solid_fraction : float
        Shadow area over window area, in a window ``margin`` away from the walls, the
        floor and the free surface (:func:`~skfem_granular.packing.solid_fraction`).
    state : str
        The protocol (``"dense"`` or ``"loose"``, :data:`~skfem_granular.packing.PROTOCOLS`).
    shape : str
    seed : int
    d_mean, size_ratio : float
        Mean area-equivalent diameter and ``d_max / d_min``.
    E : float
        Contact stiffness the packing was deposited with (its overlaps are at rest
        under this stiffness: collapse runs use the same).
    window : (x0, y0, x1, y1)
        Where ``solid_fraction`` was measured.

    Equality compares the scalar fields (compare outlines with ``numpy.array_equal``).
    settle_time, wall_time : float
        Simulated time of the deposition and the wall time it took (s).
    max_overlap : float
        Largest overlap area of two grains at rest over the smaller grain's area (the
        compression of the contact law under the column's weight; a scene starting
        from the packing allows it, ``Scene.overlap_tolerance``).
    """

    outlines: tuple = field(compare=False)
    density: float
    width: float
    height: float
    solid_fraction: float
    state: str
    shape: str
    seed: int
    d_mean: float
    size_ratio: float
    E: float
    window: tuple = (0.0, 0.0, 0.0, 0.0)
    settle_time: float = 0.0
    max_overlap: float = 0.0
    wall_time: float = field(default=0.0, compare=False)

    @property
    def n(self) -> int:
        """Number of grains."""
        return len(self.outlines)

    @property
    def aspect(self) -> float:
        """``a = H0 / L0``."""
        return self.height / self.width

    @property
    def d_max(self) -> float:
        """Largest area-equivalent diameter of the size distribution."""
        return 2.0 * self.d_mean * self.size_ratio / (1.0 + self.size_ratio)

    def meta(self) -> dict:
        """The scalar fields as plain JSON-able values."""
        d = {k: v for k, v in asdict(self).items() if k != "outlines"}
        d["window"] = [float(v) for v in self.window]
        return d

    def save(self, path) -> Path:
        """Write the packing to ``path`` (``.npz`` added if missing; plain arrays and a JSON
        header), at a temporary name renamed when complete (an earlier file stays whole)."""
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_name(path.name + ".npz")
        V, counts = pad_outlines([np.asarray(P, dtype=float) for P in self.outlines])
        meta = np.array(json.dumps(self.meta()))
        return atomic_write(path, lambda tmp: np.savez(tmp, vertices=V, counts=counts,
                                                       meta=meta))


def load_packing(path) -> Packing:
    """Read a packing written by :meth:`Packing.save` (no pickle).

    Raises
    ------
    ValueError
        One line naming the file, when it is missing or not a packing.
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            V, counts, meta = z["vertices"], z["counts"], json.loads(str(z["meta"]))
    except FileNotFoundError:
        raise ValueError(f"packing file {str(path)!r}: not found") from None
    except (OSError, KeyError, ValueError) as exc:
        raise ValueError(f"packing file {str(path)!r}: not a packing (.npz with vertices, "
                         f"counts and meta: {exc})") from None
    names = {f.name for f in fields(Packing)} - {"outlines"}
    required = {f.name for f in fields(Packing) if f.default is MISSING} - {"outlines"}
    if not required <= set(meta) <= names:
        raise ValueError(f"packing file {str(path)!r}: meta fields {sorted(meta)}: must be "
                         f"{sorted(required)}, and optionally {sorted(names - required)}")
    outlines = tuple(V[k, : counts[k]].T.copy() for k in range(len(counts)))
    meta["window"] = tuple(meta["window"])
    return Packing(outlines=outlines, **meta)
