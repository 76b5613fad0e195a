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
the particle's share of the domain, plus the triangles lining the narrow gaps between
packed particles. It is within a factor 3 of the meshes
built for the bundled scenes (tested). Unknowns are 4.5 per triangle
(Taylor-Hood P2-P1: two velocity components on vertices and edges, the
pressure on vertices). The peak memory is :data:`BASE_MEMORY` plus
:data:`BYTES_PER_UNKNOWN` per unknown of the coupled scheme (the factorised
systems dominate), measured on the collapse columns of 25 to 1000 grains; the
default limit is the memory this machine has available when the run starts.
Once the mesh exists, :meth:`Budget.check_unknowns` repeats the memory check with
its exact unknowns, before anything is assembled or factorised.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Peak memory of a coupled run per unknown, by coupling scheme (bytes), above
#: :data:`BASE_MEMORY`. Measured peaks over 10 steps (benchmarks/memory_estimate.py):
#: dense collapse columns (core ratio 0.9) at 0.04, 0.15, 0.6 and 1.5 million unknowns,
#: monolithic 0.46, 0.72, 2.88, 6.81 GB (the SuperLU factors of the coupled system), split
#: 0.31, 0.56, 1.60, 3.69 GB; the paper's particle at 267k unknowns 1.96 and 1.01 GB.
#: The estimate from the built mesh is 0.78-1.35 times these peaks, before meshing
#: 0.88-1.36 times.
BYTES_PER_UNKNOWN = {"monolithic": 5000.0, "partitioned": 5000.0, "split": 2500.0}
#: The interpreter with the libraries loaded, the scene and its bookkeeping (bytes).
BASE_MEMORY = 200e6
#: The limit where the machine's available memory is unknown (bytes).
DEFAULT_MEMORY = 16e9
#: Unknowns per triangle of a Taylor-Hood mesh (4 velocity, 0.5 pressure).
UNKNOWNS_PER_TRIANGLE = 4.5
#: Share of the triangles lining a narrow gap that the graded count does not hold already:
#: fitted on the dense 1000-grain column at core ratio 0.9 (benchmarks/memory_estimate.py
#: columns); with it the estimate is 1.02-1.16 times the meshes of the dense and loose
#: columns of 25-1000 grains at core ratio 0.9 (without: 0.59-0.88), 1.82-1.93 at 0.7.
LINED_SHARE = 0.45
#: The field meshes' growth factor when the scene gives none.
FIELD_SIGMA = 1.2


class BudgetError(ValueError):
    """A run beyond a :class:`Budget` limit (one line: parameter, estimate, limit)."""


@dataclass(frozen=True)
class Estimate:
    """What a run will cost (see :func:`estimate`); mesh figures are 0 for a dry scene."""

    steps: float
    triangles: float = 0.0
    scheme: str = "monolithic"

    @property
    def unknowns(self) -> float:
        return UNKNOWNS_PER_TRIANGLE * self.triangles

    @property
    def memory(self) -> float:
        """Bytes at the run's peak."""
        return peak_memory(self.unknowns, self.scheme)


def peak_memory(unknowns: float, scheme: str = "monolithic") -> float:
    """Estimated peak bytes of a coupled run with ``unknowns`` (velocity and pressure) and
    the coupling ``scheme``: :data:`BASE_MEMORY` plus :data:`BYTES_PER_UNKNOWN`."""
    return BASE_MEMORY + BYTES_PER_UNKNOWN[scheme] * unknowns


def taylor_hood_unknowns(mesh) -> int:
    """Velocity (P2, two components) and pressure (P1) unknowns of a triangle mesh."""
    vertices, edges = mesh.p.shape[1], mesh.facets.shape[1]
    return 2 * (vertices + edges) + vertices


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
    max_memory : float, optional
        Bytes at the run's peak; default: the memory this machine has available when the
        run is checked (:func:`skfem_granular.memory.available`; 16 GB where unknown).
    """

    max_steps: int = 100_000
    max_elements: int = 2_000_000
    max_memory: float | None = None

    def __post_init__(self):
        _bounded("max_steps (--max-steps)", self.max_steps, 1)
        _bounded("max_elements (--max-elements)", self.max_elements, 100)
        if self.max_memory is not None:
            _bounded("max_memory (--max-memory)", self.max_memory, 1e6)

    def _memory_limit(self) -> tuple[float, str]:
        """The limit in bytes and how a refusal names it."""
        if self.max_memory is not None:
            return self.max_memory, f"max_memory = {self.max_memory / 1e9:.3g} GB"
        from .. import memory

        left = memory.available()
        if left is None:
            return DEFAULT_MEMORY, f"max_memory = {DEFAULT_MEMORY / 1e9:.3g} GB"
        return left, f"the {left / 1e9:.3g} GB this machine has available"

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
        est = Estimate(scene.time.t_end / scene.time.dt, triangles(scene, cores),
                       scene.coupling)
        what = _size_parameter(scene)
        if est.triangles > self.max_elements:
            raise BudgetError(
                f"{what}: the mesh would have about {est.triangles:.3g} triangles, more than "
                f"max_elements = {self.max_elements:.3g}; use a coarser mesh or raise the "
                "limit (--max-elements)")
        self._check_memory(what, est.unknowns, scene.coupling, "would need")
        return est

    def check_unknowns(self, scene, unknowns: int) -> None:
        """Refuse a built mesh whose ``unknowns`` would need more than the memory limit
        (before anything is assembled or factorised)."""
        self._check_memory(_size_parameter(scene) + " (the mesh built)", unknowns,
                           scene.coupling, "need")

    def _check_memory(self, what: str, unknowns: float, scheme: str, verb: str) -> None:
        need = peak_memory(unknowns, scheme)
        limit, named = self._memory_limit()
        if need > limit:
            split = "" if scheme == "split" else " the split coupling,"
            raise BudgetError(
                f"{what}: about {unknowns:.3g} unknowns ({scheme} coupling) {verb} about "
                f"{need / 1e9:.3g} GB, more than {named}; use a coarser mesh,{split} or "
                "raise the limit (--max-memory, in GB)")


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
    return total + _lined_gaps(cores, edges)


def _lined_gaps(cores, edges) -> float:
    """Triangles the meshers add in the narrow gaps between particles.

    A gap narrower than ``GAP_NARROW`` outline edges is lined with outline nodes
    ``GAP_SPACING`` of its width apart and about three elements across
    (:mod:`meshing.gaps`): ``(1 / GAP_SPACING)^2 / a`` triangles per unit length over the
    local width ``g``. Between two near-circles of circumradii ``r_i, r_j`` a distance
    ``g0`` apart the width is ``g0 + k s^2`` (``k = 1/(2 r_i) + 1/(2 r_j)``, ``s`` along
    the gap), narrow out to ``g = GAP_NARROW`` edges, so the pair adds
    ``(1 / GAP_SPACING)^2 / a * 2 atan(s_max sqrt(k / g0)) / sqrt(k g0)`` triangles,
    :data:`LINED_SHARE` of which the graded count above does not already hold.
    """
    if len(cores) < 2:
        return 0.0
    from scipy.spatial import cKDTree

    from meshing.gaps import GAP_NARROW, GAP_SPACING

    c = np.array([P.mean(axis=1) for P in cores])
    r0 = np.array([float(np.max(np.hypot(*(P - P.mean(axis=1)[:, None])))) for P in cores])
    edge = np.asarray(edges)
    reach = 2.0 * float(r0.max()) + GAP_NARROW * float(edge.max())
    pairs = cKDTree(c).query_pairs(reach, output_type="ndarray")
    if not len(pairs):
        return 0.0
    i, j = pairs.T
    e = np.minimum(edge[i], edge[j])
    g0 = np.hypot(*(c[i] - c[j]).T) - r0[i] - r0[j]
    narrow = g0 < GAP_NARROW * e
    i, j, e = i[narrow], j[narrow], e[narrow]
    g0 = np.maximum(g0[narrow], 0.1 * e)  # circumcircles overlap where polygons touch
    k = 0.5 / r0[i] + 0.5 / r0[j]
    s_max = np.sqrt(np.maximum(GAP_NARROW * e - g0, 0.0) / k)
    per_length = 1.0 / (GAP_SPACING**2 * math.sqrt(3.0) / 4.0)
    lined = per_length * 2.0 / np.sqrt(k * g0) * np.arctan(s_max * np.sqrt(k / g0))
    return LINED_SHARE * float(lined.sum())
