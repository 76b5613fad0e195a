"""What a study is: its name, its runs (:class:`Run`, :func:`plan`) and the table's columns.

``"single-particle"`` runs the bundled scene ``single_particle`` (the paper's
sinking 24-gon) on uniform and graded meshes and several time steps;
``"faxen"`` the steady drag on a disk in a closed channel (:data:`FAXEN`),
whose analytic value is :func:`faxen_drag`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TypedDict

from ..scene import bundled

STUDIES = ("single-particle", "faxen")
SCENE = bundled("single_particle")


class _Channel(TypedDict):
    box: tuple[float, float, float, float]
    a: float
    l: float


#: the Faxen channel: its box, the disk's radius ``a`` and the channel's half-width ``l``
FAXEN: _Channel = {"box": (-3.0, -1.0, 3.0, 1.0), "a": 0.2, "l": 1.0}
COLUMNS = ("key", "family", "kind", "n_sides", "h", "delta_l", "sigma", "dt", "seed",
           "vertices", "p2_nodes", "dofs", "wall_time", "wall_meshing", "wall_assembly",
           "wall_solve", "wall_other", "wall_warmup", "peak_rss_mb", "quantity", "value",
           "reference", "reference_value", "error", "error_curve", "mirror_symmetric",
           "rounding_mirror", "rounding_renumber", "rounding_field")


@dataclass(frozen=True)
class Run:
    """One discretisation of a study (``seed``: node renumbering, 0 = none)."""

    family: str  # "uniform" | "graded" | "sigma" | "dt"
    kind: str  # mesh kind
    h: float | None = None
    delta_l: float | None = None
    sigma: float | None = None
    dt: float | None = None
    n_sides: int | None = None
    t_end: float | None = None
    seed: int = 0

    @property
    def key(self) -> str:
        parts = [self.family, self.kind]
        for name in ("n_sides", "h", "delta_l", "sigma", "dt", "t_end"):
            v = getattr(self, name)
            if v is not None:
                parts.append(f"{name}{v:g}")
        if self.seed:
            parts.append(f"perm{self.seed}")
        return "_".join(parts)

    @property
    def mesh_key(self) -> str:
        """The key of the unpermuted run on the same mesh and step."""
        return replace(self, seed=0).key


def plan(study: str, smoke: bool = False) -> list[Run]:
    """The runs of ``study``; ``smoke`` gives a small grid of short runs (minutes in all)."""
    if study not in STUDIES:
        raise ValueError(f"study = {study!r}: must be one of {', '.join(STUDIES)}")
    if study == "faxen":
        return _plan_faxen(smoke)
    e = 2 * 0.5e-3 * math.sin(math.pi / 24)  # the scene's 24-gon outline edge
    dt0, t_end = 1e-5, (1e-4 if smoke else None)
    uni: list[tuple[float, float | None]]  # (h, delta_l)
    gra: list[tuple[float | None, float | None]]  # (delta_l, sigma)
    dts: tuple[float, ...]
    seeds: dict[str, list[float | None]]  # the runs renumbered: their delta_l / h
    if smoke:
        uni = [(0.26e-3, None), (e, None)]
        gra = [(None, None), (None, 1.5), (e / 2, None)]
        dts = (2e-5, 1e-5, 5e-6)
        seeds = {"graded": [None], "uniform": [0.26e-3]}
        n_seeds = 2
    else:
        uni = [(0.2e-3, None), (e, None), (e / 2, e / 2)]
        gra = [(dl, s) for dl in (None, e / 2) for s in (None, 1.15, 1.5)]
        dts = (4e-5, 2e-5, 1e-5, 5e-6, 2.5e-6)
        seeds = {"graded": [None, e / 2], "uniform": [0.2e-3, e]}
        n_seeds = 3
    runs = [Run("uniform", "uniform", h=h, delta_l=dl, dt=dt0, t_end=t_end) for h, dl in uni]
    runs += [Run("graded" if s is None else "sigma", "graded", delta_l=dl, sigma=s, dt=dt0,
                 t_end=t_end) for dl, s in gra]
    runs += [Run("dt", "graded", dt=dt, t_end=t_end) for dt in dts if dt != dt0]
    for r in list(runs):
        if r.family in ("uniform", "graded") and (r.h if r.family == "uniform" else r.delta_l) \
                in seeds[r.family]:
            runs += [replace(r, seed=k) for k in range(1, n_seeds + 1)]
    return runs


def _plan_faxen(smoke):
    ns_g = (12, 24, 48) if smoke else (12, 16, 24, 32, 48, 64, 96, 128)
    ns_s = (12, 24, 48) if smoke else (12, 24, 48, 96, 128)
    ns_u = (12, 16) if smoke else (12, 16, 24, 32)
    runs = [Run("graded", "graded", n_sides=n) for n in ns_g]
    runs += [Run("sigma", "graded", n_sides=n, sigma=s) for s in (1.2, 1.5) if not smoke or s == 1.5
             for n in ns_s]
    runs += [Run("uniform", "uniform", n_sides=n) for n in ns_u]
    n_seeds = 2 if smoke else 3
    runs += [replace(r, seed=k) for r in list(runs) if r.family != "sigma"
             for k in range(1, n_seeds + 1)]
    return runs


def faxen_drag(k: float) -> float:
    """Faxen's F/(mu U) for a cylinder on the centre line of a closed channel (k = a/l)."""
    s = math.log(1 / k) - 0.9157 + 1.7244 * k**2 - 1.7302 * k**4 + 2.4056 * k**6 - 4.5913 * k**8
    return 4 * math.pi / s
