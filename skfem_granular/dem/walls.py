"""Fixed walls: convex polygons that never move (same outline for DEM and fluid)."""

from __future__ import annotations

import numpy as np

from .particles import pad_outlines
from .polygon import Polygon

__all__ = ["WallArrays", "box_walls", "incline_wall"]


def box_walls(x0: float, y0: float, x1: float, y1: float, thickness: float) -> list[Polygon]:
    """Four walls of width ``thickness`` around the box ``[x0, x1] x [y0, y1]``.

    Returns bottom, right, top, left; the side walls cover the corners.
    The paper's geometry is ``box_walls(0, 0, 3e-3, 11e-3, 0.5e-3)``.
    """
    if not (x1 > x0 and y1 > y0):
        raise ValueError(f"box ({x0}, {y0}, {x1}, {y1}): must have x1 > x0 and y1 > y0")
    if not (np.isfinite(thickness) and thickness > 0):
        raise ValueError(f"wall thickness = {thickness}: must be finite and > 0")
    t = thickness
    return [
        Polygon.rectangle(x0, y0 - t, x1, y0),
        Polygon.rectangle(x1, y0 - t, x1 + t, y1 + t),
        Polygon.rectangle(x0, y1, x1, y1 + t),
        Polygon.rectangle(x0 - t, y0 - t, x0, y1 + t),
    ]


def incline_wall(angle: float, length: float, thickness: float, origin=(0.0, 0.0)) -> Polygon:
    """A slab whose top surface runs from ``origin`` upwards at ``angle`` (radians)."""
    c, s = np.cos(angle), np.sin(angle)
    o = np.asarray(origin, dtype=float)
    along, down = np.array([c, s]), np.array([s, -c])
    P = np.column_stack([o + thickness * down, o + length * along + thickness * down,
                         o + length * along, o])
    return Polygon(P, name="incline")


class WallArrays:
    """Padded world outlines of all walls.

    Attributes
    ----------
    vertices
        ``(W, nmax, 2)`` padded vertices (padding repeats the first vertex).
    count
        ``(W,)`` true vertex counts.
    centroid
        ``(2, W)`` centroids.
    """

    def __init__(self, walls):
        polys = []
        for k, w in enumerate(walls):
            polys.append(w if isinstance(w, Polygon) else Polygon(w, f"walls[{k}]"))
        self.polygons = polys
        if polys:
            self.vertices, self.count = pad_outlines([p.vertices for p in polys])
            self.centroid = np.column_stack([p.centroid for p in polys])
        else:
            self.vertices, self.count = np.zeros((0, 3, 2)), np.zeros(0, dtype=np.int64)
            self.centroid = np.zeros((2, 0))

    @property
    def n(self) -> int:
        """Number of walls."""
        return len(self.polygons)

    def outlines(self) -> list[np.ndarray]:
        """``(2, n)`` counter-clockwise outline of every wall."""
        return [p.vertices.copy() for p in self.polygons]
