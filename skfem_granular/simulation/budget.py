"""What a run will cost, estimated and checked against stated limits before any work.

:func:`estimate` gives, from the scene alone (and the particle cores), the
number of time steps, mesh triangles, unknowns and the memory of the
factorised systems; :meth:`Budget.check` refuses, in one line that names the
parameter, the estimate and the limit, a run beyond a :class:`Budget`'s limits
before the mesh is built or a step taken. Raise a limit with the command
line's ``--max-steps``, ``--max-elements``, ``--max-memory`` or
``Simulation(..., budget=Budget(...))``.

The triangle count integrates the meshes' size field: about ``delta_l`` (the
outline edge) at a particle's outline, growing by ``sigma - 1`` per unit of
distance (graded and field meshes; ``h`` everywhere for uniform ones) up to
the particle's share of the domain. It is within a factor 3 of the meshes
built for the bundled scenes (tested). Unknowns are 4.5 per triangle
(Taylor-Hood P2-P1: two velocity components on vertices and edges, the
pressure on vertices); memory :data:`BYTES_PER_UNKNOWN` per unknown (the
single particle with ``delta_l = 1e-5``: 267k unknowns, 2.4 GB peak, measured).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Peak memory per unknown of a coupled run (bytes): 2.4 GB at 267k unknowns, measured
#: (the 95k-unknown benchmark: 6 kB per unknown).
BYTES_PER_UNKNOWN = 9000.0
#: Unknowns per triangle of a Taylor-Hood mesh (4 velocity, 0.5 pressure).
UNKNOWNS_PER_TRIANGLE = 4.5
#: The field meshes' growth factor when the scene gives none.
FIELD_SIGMA = 1.2


class BudgetError(ValueError):
    """A run beyond a :class:`Budget` limit (one line: parameter, estimate, limit)."""


@dataclass(frozen=True)
class Estimate:
    """What a run will cost (see :func:`estimate`); mesh figures are 0 for a dry scene."""

    steps: float
    triangles: float = 0.0

    @property
    def unknowns(self) -> float:
        return UNKNOWNS_PER_TRIANGLE * self.triangles

    @property
    def memory(self) -> float:
        """Bytes."""
        return BYTES_PER_UNKNOWN * self.unknowns


def _bounded(name: str, value, lo: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
            math.isfinite(value) and value >= lo):
        raise ValueError(f"{name} = {value!r}: must be a finite number >= {lo:g}")
    return value


@dataclass(frozen=True)
class Budget:
    """Limits a run is checked against before it starts.

    Parameters
    ----------
    max_steps : int
        Time steps (``time.t_end / time.dt``; adaptive runs: their largest step);
        the default is 50 times the longest bundled scene's.
    max_elements : int
        Mesh triangles.
    max_memory : float
        Bytes of the factorised systems (default 16 GB).
    """

    max_steps: int = 100_000
    max_elements: int = 2_000_000
    max_memory: float = 16e9

    def __post_init__(self):
        _bounded("max_steps (--max-steps)", self.max_steps, 1)
        _bounded("max_elements (--max-elements)", self.max_elements, 100)
        _bounded("max_memory (--max-memory)", self.max_memory, 1e6)

    def check_steps(self, scene) -> None:
        """Refuse a run of more than :attr:`max_steps` steps (before anything is built)."""
        steps = scene.time.t_end / scene.time.dt
        if steps > self.max_steps:
            raise BudgetError(
                f"time.t_end / time.dt = {scene.time.t_end:g} / {scene.time.dt:g} = {steps:.3g} "
                f"steps: more than max_steps = {self.max_steps:.3g}; use a larger time.dt, a "
                "smaller time.t_end, or raise the limit (--max-steps)")

    def check_mesh(self, scene, cores) -> Estimate:
        """Refuse a mesh beyond :attr:`max_elements` or :attr:`max_memory` (before meshing)."""
        est = Estimate(scene.time.t_end / scene.time.dt, triangles(scene, cores))
        what = _size_parameter(scene)
        if est.triangles > self.max_elements:
            raise BudgetError(
                f"{what}: the mesh would have about {est.triangles:.3g} triangles, more than "
                f"max_elements = {self.max_elements:.3g}; use a coarser mesh or raise the "
                "limit (--max-elements)")
        if est.memory > self.max_memory:
            raise BudgetError(
                f"{what}: about {est.unknowns:.3g} unknowns would need about "
                f"{est.memory / 1e9:.3g} GB, more than max_memory = "
                f"{self.max_memory / 1e9:.3g} GB; use a coarser mesh or raise the limit "
                "(--max-memory, in GB)")
        return est


def _size_parameter(scene) -> str:
    """The scene fields that set the mesh size, as the refusal names them."""
    m = scene.mesh
    parts = [f"mesh.{k} = {getattr(m, k):g}" for k in ("delta_l", "h", "sigma")
             if getattr(m, k) is not None]
    return ", ".join(parts) if parts else "mesh (the particles' own outline edges)"


def _domain(scene) -> tuple[float, float]:
    """Area and bounding-box diagonal of the domain."""
    D = np.asarray(scene.domain, dtype=float)
    if D.ndim == 1:
        x0, y0, x1, y1 = D
        return (x1 - x0) * (y1 - y0), math.hypot(x1 - x0, y1 - y0)
    x, y = D
    area = 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)))
    return area, math.hypot(np.ptp(x), np.ptp(y))


def _graded_count(r0: float, dl: float, q: float, R: float) -> float:
    """Triangles of a size field ``dl + q (r - r0)`` on the annulus ``r0 < r < R``."""
    a = math.sqrt(3.0) / 4.0
    if R <= r0:
        return 0.0
    U = dl + q * (R - r0)
    # integral of 2 pi r / (a h(r)^2) dr, with h = dl + q (r - r0)
    return 2.0 * math.pi / (a * q) * ((r0 - dl / q) * (1.0 / dl - 1.0 / U)
                                      + math.log(U / dl) / q)


def triangles(scene, cores) -> float:
    """Estimated triangles of the scene's fluid mesh around the particle ``cores`` ``(2, N)``."""
    m = scene.mesh
    area, _ = _domain(scene)
    a = math.sqrt(3.0) / 4.0
    edges = [float(np.mean(np.hypot(*(np.roll(P, -1, axis=1) - P)))) for P in cores]
    if m.kind == "uniform" or not cores:
        h = m.h if m.h is not None else (m.delta_l or float(np.mean(edges)))
        return area / (a * h * h)
    share = math.sqrt(area / (math.pi * len(cores)))  # a particle's share of the domain
    total = 0.0
    for P, edge in zip(cores, edges, strict=True):
        c = P.mean(axis=1)
        r0 = float(np.max(np.hypot(*(P - c[:, None]))))
        dl = min(m.delta_l or edge, edge)
        if m.sigma is not None:
            q = m.sigma - 1.0
        elif m.kind == "graded" or (m.kind == "auto" and len(cores) == 1):
            q = dl / r0
        else:
            q = FIELD_SIGMA - 1.0
        if m.kind == "group" and m.h is not None:
            dl = min(dl, m.h)
        total += _graded_count(r0, dl, q, max(share, r0))
    return total
