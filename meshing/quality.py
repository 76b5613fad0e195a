"""Element quality: angles, aspect ratio, sizes; mesh statistics; remeshing trigger.

The aspect ratio used throughout is circumradius over twice the inradius,
``R / (2 r)``: 1 for an equilateral triangle, growing without bound as a
triangle degenerates. (The paper's band ``0.5 <= eps <= 2`` for an edge-ratio
measure is replaced by this one; :data:`MERGE_ASPECT` is the threshold above
which cleanup merges a triangle with its neighbours.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .value import mesh_of

MERGE_ASPECT = 2.0
"""Triangles with ``R / (2 r)`` above this are degenerate and get merged."""


def signed_areas(p: NDArray[np.float64], t: NDArray[np.int64]) -> NDArray[np.float64]:
    """Signed triangle areas ``(T,)``, positive for counter-clockwise triangles."""
    a, b, c = p[:, t[0]], p[:, t[1]], p[:, t[2]]
    return 0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))


def edge_lengths(p: NDArray[np.float64], t: NDArray[np.int64]) -> NDArray[np.float64]:
    """Edge lengths ``(3, T)``; row ``k`` is the edge opposite vertex ``k``."""
    q = p[:, t]                                             # (2, 3, T)
    d = q[:, [2, 0, 1]] - q[:, [1, 2, 0]]
    return np.hypot(d[0], d[1])


def _angles(L: NDArray[np.float64]) -> NDArray[np.float64]:
    a, b, c = L, np.roll(L, -1, axis=0), np.roll(L, -2, axis=0)
    cosv = np.clip((b * b + c * c - a * a) / np.maximum(2.0 * b * c, 1e-300), -1.0, 1.0)
    return np.degrees(np.arccos(cosv))


def _aspect(L: NDArray[np.float64], area: NDArray[np.float64]) -> NDArray[np.float64]:
    a, b, c = L
    s = 0.5 * (a + b + c)
    with np.errstate(divide="ignore", invalid="ignore"):
        # R = abc / (4A), r = A / s  =>  R / (2r) = abc s / (8 A^2)
        q = a * b * c * s / (8.0 * area * area)
    return np.where(area > 0.0, q, np.inf)


def angles(p: NDArray[np.float64], t: NDArray[np.int64]) -> NDArray[np.float64]:
    """Interior angles in degrees ``(3, T)``; row ``k`` at vertex ``k``."""
    return _angles(edge_lengths(p, t))


def aspect_ratio(p: NDArray[np.float64], t: NDArray[np.int64]) -> NDArray[np.float64]:
    """``R / (2 r)`` per triangle ``(T,)``; ``inf`` for zero or negative area."""
    return _aspect(edge_lengths(p, t), signed_areas(p, t))


def angles_and_aspect(p: NDArray[np.float64], t: NDArray[np.int64]
                      ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`angles` and :func:`aspect_ratio` from one pass over the edges."""
    L = edge_lengths(p, t)
    return _angles(L), _aspect(L, signed_areas(p, t))


@dataclass(frozen=True)
class MeshStats:
    """Size and quality figures of a triangle mesh (angles in degrees).

    ``n_p2_nodes`` counts vertices plus edges: the node count of a P2
    (Taylor-Hood velocity) discretisation. ``aspect_quantiles`` are the 0, 50,
    90, 99 and 100 % quantiles of ``R / (2 r)``; ``size_ratio`` is the largest
    over the smallest triangle area's square root (a length ratio).
    """

    n_vertices: int
    n_edges: int
    n_p2_nodes: int
    n_triangles: int
    min_angle: float
    max_angle: float
    mean_aspect: float
    max_aspect: float
    aspect_quantiles: tuple[float, float, float, float, float]
    n_inverted: int
    size_ratio: float
    min_edge: float
    max_edge: float


def triangle_stats(p: NDArray[np.float64], t: NDArray[np.int64]) -> MeshStats:
    """:class:`MeshStats` of a point array ``(2, n)`` and triangles ``(3, T)``."""
    used = np.unique(t)
    e = np.sort(np.hstack([t[[0, 1]], t[[1, 2]], t[[2, 0]]]), axis=0)
    n_edges = np.unique(e[0] * (p.shape[1] + 1) + e[1]).size
    L = edge_lengths(p, t)
    ang = _angles(L)
    area = signed_areas(p, t)
    q = _aspect(L, area)
    area = np.abs(area)
    finite = q[np.isfinite(q)]
    quant = tuple(float(v) for v in np.quantile(q, [0.0, 0.5, 0.9, 0.99, 1.0],
                                                 method="inverted_cdf"))
    return MeshStats(
        n_vertices=int(used.size), n_edges=int(n_edges), n_p2_nodes=int(used.size + n_edges),
        n_triangles=int(t.shape[1]), min_angle=float(ang.min()), max_angle=float(ang.max()),
        mean_aspect=float(finite.mean()) if finite.size else float("inf"),
        max_aspect=float(q.max()), aspect_quantiles=quant,  # type: ignore[arg-type]
        n_inverted=int(np.sum(signed_areas(p, t) <= 0.0)),
        size_ratio=float(np.sqrt(area.max() / max(area.min(), 1e-300))),
        min_edge=float(L.min()), max_edge=float(L.max()))


def mesh_stats(mesh) -> MeshStats:
    """Statistics of a ``skfem.MeshTri`` or a :class:`meshing.BodyFittedMesh`'s mesh
    (see :class:`MeshStats`).

    Examples
    --------
    >>> import meshing
    >>> s = meshing.mesh_stats(meshing.uniform_mesh((0, 0, 1, 1), [], h=0.25))
    >>> s.min_angle >= 30.0
    True
    """
    mesh = mesh_of(mesh)
    return triangle_stats(np.asarray(mesh.p), np.asarray(mesh.t, dtype=np.int64))


def remesh_needed(mesh, min_angle: float = 15.0, max_aspect: float = 5.0) -> bool:
    """Whether a (moved) mesh has degraded enough to be rebuilt.

    True when any triangle is inverted or has zero area (its signed area, with
    the counter-clockwise orientation the builders produce, is <= 0), when the
    smallest angle is below ``min_angle`` degrees, or when an aspect ratio
    ``R / (2 r)`` exceeds ``max_aspect``. Freshly built meshes satisfy
    ``min_angle >= 20`` and ``max_aspect <= 3``, so the defaults leave room
    for some motion.

    Parameters
    ----------
    mesh
        ``skfem.MeshTri`` or :class:`meshing.BodyFittedMesh`, typically
        from :func:`meshing.move_particles`.
    min_angle
        Smallest acceptable angle in degrees, ``0 < min_angle < 60``.
    max_aspect
        Largest acceptable ``R / (2 r)``, ``> 1``.
    """
    if not 0.0 < min_angle < 60.0:
        raise ValueError(f"min_angle: must be in (0, 60) degrees, got {min_angle!r}")
    if not max_aspect > 1.0:
        raise ValueError(f"max_aspect: must be > 1, got {max_aspect!r}")
    mesh = mesh_of(mesh)
    p, t = np.asarray(mesh.p), np.asarray(mesh.t, dtype=np.int64)
    if np.any(signed_areas(p, t) <= 0.0):
        return True
    ang, q = angles_and_aspect(p, t)
    return bool(ang.min() < min_angle or q.max() > max_aspect)
