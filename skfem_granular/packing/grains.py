"""Grain outlines of a packing: shapes and a size distribution, drawn from a seeded generator.

A grain's size is its *area-equivalent diameter* ``d = 2 sqrt(A / pi)``; sizes are
uniform in ``[d_min, d_max]`` with ``d_max / d_min = size_ratio`` and mean ``d_mean``
(Kumar, Delenne & Soga's discs: ``d_max / d_min = 1.8``). Outlines are ``(2, k)``,
counter-clockwise, centred on their centroid.
"""

from __future__ import annotations

import numpy as np

from ..dem import Polygon

__all__ = ["SHAPES", "diameter_range", "grain_outlines"]

#: grain shapes: near-disks (regular n-gons, ``sides`` of them), regular hexagons,
#: irregular convex polygons (hull of random points on an ellipse of aspect 0.7)
SHAPES = ("ngon", "hexagon", "irregular")


def diameter_range(d_mean: float, size_ratio: float) -> tuple[float, float]:
    """``(d_min, d_max)`` of a uniform distribution with mean ``d_mean``, ratio ``size_ratio``."""
    d_min = 2.0 * d_mean / (1.0 + size_ratio)
    return d_min, size_ratio * d_min


def _unit_outline(shape: str, sides: int, rng) -> np.ndarray:
    """An outline of unit area-equivalent diameter, random orientation, centred."""
    if shape == "irregular":
        from scipy.spatial import ConvexHull  # scipy.spatial: imported when used

        phi = np.sort(rng.uniform(0.0, 2.0 * np.pi, 7))
        r = rng.uniform(0.85, 1.0, 7)
        pts = np.column_stack([r * np.cos(phi), 0.7 * r * np.sin(phi)])
        V = pts[ConvexHull(pts).vertices].T  # counter-clockwise in 2D
    else:
        V = Polygon.regular(6 if shape == "hexagon" else sides, 1.0).vertices
    a = rng.uniform(0.0, 2.0 * np.pi)
    c, s = np.cos(a), np.sin(a)
    V = np.array([[c, -s], [s, c]]) @ V
    P = Polygon(V)
    return (V - P.centroid[:, None]) / (2.0 * np.sqrt(P.area / np.pi))


def grain_outlines(n: int, shape: str, d_mean: float, size_ratio: float, rng,
                   sides: int = 12) -> list[np.ndarray]:
    """``n`` grain outlines ``(2, k)`` centred at the origin, sizes uniform in diameter.

    Parameters
    ----------
    n : int
        Number of grains.
    shape : {"ngon", "hexagon", "irregular"}
        See :data:`SHAPES`.
    d_mean : float
        Mean area-equivalent diameter (m).
    size_ratio : float
        ``d_max / d_min`` (1: monodisperse).
    rng : numpy.random.Generator
        The seeded source of sizes, shapes and orientations.
    sides : int
        Vertex count of the near-disks (``shape = "ngon"``).
    """
    d_min, d_max = diameter_range(d_mean, size_ratio)
    d = rng.uniform(d_min, d_max, n) if size_ratio > 1.0 else np.full(n, d_mean)
    return [d[k] * _unit_outline(shape, sides, rng) for k in range(n)]
