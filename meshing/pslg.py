"""Node layout of a mesh under construction and its constrained Delaunay triangulation.

A :class:`Layout` holds the nodes sorted by how they may move:

* ``wall``: nodes on the domain outline (corners first and then
  ``n_wall_fixed`` further nodes, never moved; the others slide along their
  edge),
* ``particles``: particle outlines (never moved),
* ``fixed``: other nodes that are never moved (a group's fine region and its
  transition polygon) with optional interior segments between them,
* ``free``: interior nodes that cleanup and relaxation may remove or move.

:func:`triangulate` joins them with the ``triangle`` package's constrained
Delaunay mode (``p``, no quality switches, so no Steiner points) and returns
segment markers from which named boundaries are built.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import triangle
from numpy.typing import NDArray

from .geometry import centroids

INTERIOR_MARKER = 1
"""Segment marker of interior constraint segments (a group's transition)."""


@dataclass
class Layout:
    """Nodes and constraints of a mesh under construction (see module docstring)."""

    domain: NDArray[np.float64]
    edge_names: tuple[str, ...]
    particles: list[NDArray[np.float64]]
    wall: NDArray[np.float64]
    wall_edge: NDArray[np.int64]
    free: NDArray[np.float64]
    fixed: NDArray[np.float64] = field(default_factory=lambda: np.zeros((2, 0)))
    fixed_segments: NDArray[np.int64] = field(
        default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    n_wall_fixed: int = 0
    """Wall nodes after the corners that never move (a group's fine region).
    ``fixed_segments`` index ``fixed``; a negative entry ``-1 - i`` means the
    frozen wall node ``i`` (corners and fixed wall nodes keep their indices)."""

    @property
    def n_wall_frozen(self) -> int:
        """Leading wall nodes that never move: corners and fixed wall nodes."""
        return self.n_corners + self.n_wall_fixed

    @property
    def n_corners(self) -> int:
        return self.domain.shape[1]

    @property
    def n_wall(self) -> int:
        return self.wall.shape[1]

    @property
    def n_particle_nodes(self) -> int:
        return sum(P.shape[1] for P in self.particles)

    @property
    def n_frozen(self) -> int:
        """Number of leading nodes that never move: walls, particles, fixed."""
        return self.n_wall + self.n_particle_nodes + self.fixed.shape[1]

    def points(self) -> NDArray[np.float64]:
        """All nodes, ``(2, n)``: wall, particles, fixed, free."""
        return np.hstack([self.wall, *self.particles, self.fixed, self.free])

    def with_free(self, free: NDArray[np.float64]) -> Layout:
        return replace(self, free=free)

    def wall_parameter(self) -> NDArray[np.float64]:
        """Arc length of every wall node from the start corner of its edge."""
        A = self.domain[:, self.wall_edge]
        return np.hypot(*(self.wall - A))


def boundary_labels(layout: Layout) -> list[tuple[str, ...]]:
    """Boundary names for each segment marker ``m >= 2`` (index ``m - 2``)."""
    labels: list[tuple[str, ...]] = [("wall", name) if name else ("wall",)
                                     for name in layout.edge_names]
    labels += [(f"particle{p}",) for p in range(len(layout.particles))]
    return labels


def wall_segments(layout: Layout) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Segments along the domain outline through all wall nodes, and their markers."""
    nd = layout.n_corners
    s = layout.wall_parameter()
    segs, marks = [], []
    for j in range(nd):
        idx = np.flatnonzero(layout.wall_edge == j)
        idx = idx[np.argsort(s[idx], kind="stable")]
        chain = np.append(idx, (j + 1) % nd)
        segs.append(np.column_stack([chain[:-1], chain[1:]]))
        marks.append(np.full(chain.size - 1, 2 + j))
    return np.vstack(segs), np.concatenate(marks)


@dataclass
class Triangulation:
    """Output of :func:`triangulate`: points ``(2, n)``, triangles ``(3, T)``
    (counter-clockwise), segments ``(2, S)`` and their markers ``(S,)``."""

    points: NDArray[np.float64]
    t: NDArray[np.int64]
    segments: NDArray[np.int64]
    markers: NDArray[np.int64]



def boundary_segments(layout: Layout):
    """Wall and particle-outline segments of a layout with their markers.

    Returns ``(segments (n, 2), markers (n,), index of the first node after the outlines)``;
    particle ``p``'s outline carries the marker ``2 + n_corners + p``.
    """
    segs, marks = wall_segments(layout)
    off = layout.n_wall
    nd = layout.n_corners
    counts = np.array([P.shape[1] for P in layout.particles], dtype=np.int64)
    if counts.size:
        start = np.repeat(np.cumsum(counts) - counts, counts)
        k = np.arange(int(counts.sum()))
        nxt = np.where(k + 1 - start == np.repeat(counts, counts), start, k + 1)
        segs = np.vstack([segs, np.column_stack([off + k, off + nxt])])
        marks = np.append(marks, 2 + nd + np.repeat(np.arange(counts.size), counts))
    return segs, marks, off + int(counts.sum())


def triangulate(layout: Layout, quality: str = "") -> Triangulation:
    """Constrained Delaunay triangulation of a layout.

    Parameters
    ----------
    layout
        Nodes and constraints.
    quality
        Extra ``triangle`` switches for a quality mesh (e.g. ``"q30Ya0.0001"``);
        empty for a plain constrained Delaunay triangulation without Steiner
        points. Steiner points are appended after the layout's nodes.

    Raises
    ------
    RuntimeError
        If ``triangle`` inserted points although ``quality`` is empty
        (crossing constraints); this signals a bug in the layout code, not bad
        user input.
    """
    pts = layout.points()
    segs, marks, off = boundary_segments(layout)
    if layout.fixed_segments.size:
        fs = layout.fixed_segments
        segs = np.vstack([segs, np.where(fs >= 0, off + fs, -1 - fs)])
        marks = np.append(marks, np.full(layout.fixed_segments.shape[0], INTERIOR_MARKER))
    data = {"vertices": pts.T, "segments": segs, "segment_markers": marks[:, None]}
    if layout.particles:
        data["holes"] = centroids(layout.particles)
    out = triangle.triangulate(data, "pQ" + quality)
    if not quality and out["vertices"].shape[0] != pts.shape[1]:
        raise RuntimeError("triangle inserted Steiner points: constraints cross "
                           f"({out['vertices'].shape[0] - pts.shape[1]} extra nodes)")
    if quality:
        pts = np.ascontiguousarray(out["vertices"].T)
    return Triangulation(points=pts, t=out["triangles"].T.astype(np.int64),
                         segments=out["segments"].T.astype(np.int64),
                         markers=out["segment_markers"].ravel().astype(np.int64))


def fixed_point(x: float) -> str:
    """Format a positive number in fixed-point for a ``triangle`` switch.

    ``triangle``'s switch parser misreads exponents (``a5.8e-09``), so area
    bounds must be written without one.
    """
    digits = max(0, int(-np.floor(np.log10(x))) + 9)
    return f"{x:.{digits}f}"
