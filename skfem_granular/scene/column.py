"""The ``[column]`` section: a prepared packing standing in the tank behind a gate.

The packing (:mod:`skfem_granular.packing`, a ``.npz`` file) is placed with its
left wall on the domain's left wall and its floor on the domain's floor; the gate
is its right wall, at ``x = x0 + L0``, and is removed at ``t = 0`` (the run starts
with the column free to collapse, as in the collapse experiments and simulations
of Lajeunesse et al. 2005, Staron & Hinch 2005, Kumar et al.). ``core_ratio`` is
the fluid's outline of every grain (the hydrodynamic radius over the contact
radius). The contact stiffness is the packing's: its grains rest with the overlaps
of that stiffness, which the scene allows at the start (``Scene.overlap_tolerance``,
:data:`COLUMN_OVERLAP_FACTOR` times the packing's largest).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..dem import Polygon
from ..packing import Packing, load_packing
from ._checks import check_keys, num
from ._keys import Docs, KeyDoc, toml_keys
from .sections import ParticleSpec

__all__ = ["COLUMN_DOCS", "COLUMN_KEYS", "COLUMN_OVERLAP_FACTOR", "ColumnSpec",
           "column_particles", "gate_position"]

#: a column scene allows overlaps at the start up to this many times its packing's largest
COLUMN_OVERLAP_FACTOR = 1.5


@dataclass(frozen=True)
class ColumnSpec:
    """A column: its packing and the fluid's outline of its grains.

    Attributes
    ----------
    packing : Packing or str or Path
        The packing, or its ``.npz`` file (read by :func:`column_particles`).
    core_ratio : float
        The fluid's outline of every grain over its contact outline, in ``(0, 1]``.
    """

    packing: Packing | str | Path
    core_ratio: float = 0.8

    def __post_init__(self):
        object.__setattr__(self, "core_ratio", num("column", "core_ratio", self.core_ratio,
                                                   lo=0, hi=1))


#: The TOML keys of ``[column]``: one per field of :class:`ColumnSpec`.
COLUMN_DOCS: Docs = {
    "packing": KeyDoc("string", "the .npz file of a packing (skfem-granular pack), relative "
                      "to the scene file", "a file path"),
    "core_ratio": KeyDoc("float", "the fluid's outline of every grain: its polygon scaled by "
                         "this", "> 0 and <= 1"),
}
COLUMN_KEYS = frozenset(toml_keys(ColumnSpec, COLUMN_DOCS))


def gate_position(packing: Packing, domain) -> float:
    """``x`` of the gate: the domain's left wall plus the column's width ``L0``."""
    return float(domain[0]) + packing.width


def _check_fits(packing: Packing, domain, where: str) -> None:
    x0, y0, x1, y1 = domain
    gate = gate_position(packing, domain)
    if not gate < x1:
        raise ValueError(f"{where}: the gate at x = {gate:.6g} m (domain x0 + the column's "
                         f"width L0 = {packing.width:.6g} m) must lie inside domain.box, x < "
                         f"{x1:.6g} m")
    top = y0 + max(float(np.max(P[1])) for P in packing.outlines)
    if not top < y1:
        raise ValueError(f"{where}: the column reaches y = {top:.6g} m: must stay below the "
                         f"domain's top, y < {y1:.6g} m")


def column_particles(d: dict, domain, base=None) -> tuple[list[ParticleSpec], Packing]:
    """The grains of a ``[column]`` table, placed in ``domain``, and their packing.

    Parameters
    ----------
    d : dict
        ``{"packing": path or Packing, "core_ratio": r}``; a relative path is read
        relative to ``base`` (the scene file's directory) when given.
    domain : (x0, y0, x1, y1)
        The tank.
    base : Path, optional
    """
    if not isinstance(d, dict):
        raise ValueError(f"column = {d!r}: must be a table ([column] section)")
    check_keys("column", d, COLUMN_KEYS)
    if "packing" not in d:
        raise ValueError("column.packing: missing; give the .npz file of a packing "
                         "(skfem-granular pack)")
    packing = d["packing"]
    if not isinstance(packing, Packing):
        if not isinstance(packing, (str, Path)):
            raise ValueError(f"column.packing = {packing!r}: must be a file path (string)")
        path = Path(packing)
        if base is not None and not path.is_absolute():
            path = Path(base) / path
        packing = load_packing(path)
    spec = ColumnSpec(packing, **{k: v for k, v in d.items() if k != "packing"})
    _check_fits(packing, domain, "column.packing")
    shift = np.array([[domain[0]], [domain[1]]])
    parts = [ParticleSpec(Polygon(P + shift, name=f"column[{k}]"), packing.density,
                          core_ratio=spec.core_ratio) for k, P in enumerate(packing.outlines)]
    return parts, packing
