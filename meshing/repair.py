"""The cleanup pipeline shared by graded and group meshes, and its last resort:
repairing triangles that merging and relaxation left outside the bounds."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from .cleanup import SizeRule, merge_degenerate, near_particles
from .geometry import inside
from .pslg import Layout, Triangulation, wall_segments
from .quality import angles_and_aspect, edge_lengths
from .relax import relax

SAFE_MIN_ANGLE = 20.0
"""Guaranteed smallest angle (degrees) of a built mesh (see the builders for
the geometric condition)."""

SAFE_MAX_ASPECT = 3.0
"""Guaranteed largest ``R / (2 r)`` of a built mesh."""

REPAIR_ROUNDS = 3
"""Rounds of node insertion for triangles outside the guaranteed bounds."""


def build(layout: Layout, sizing: SizeRule, keep_out: Sequence[NDArray[np.float64]],
          relax_rounds: int) -> tuple[Layout, Triangulation]:
    """Merge degenerate triangles, relax, merge again, repair.

    Repair (at most :data:`REPAIR_ROUNDS` times, each followed by one round
    of relaxation and merging) handles triangles that still violate
    :data:`SAFE_MIN_ANGLE` or :data:`SAFE_MAX_ASPECT`, typically a short
    frozen edge (particle or wall) facing a far node; see
    :func:`repair_nodes`. Where triangles are still bad after that, one more
    round inserts its nodes as fixed ones, not relaxed: relaxation can pull an
    inserted node back out of the bad triangle's circumcircle, round after
    round (an 11-gon near a wall at sigma 1.6: 18.1 deg after every round).
    Well-shaped meshes pass through unchanged.
    """
    layout, _ = merge_degenerate(layout, sizing)
    if relax_rounds:
        layout = relax(layout, sizing, keep_out, rounds=relax_rounds)
    layout, tri = merge_degenerate(layout, sizing)
    for k in range(2 * REPAIR_ROUNDS):
        free, wall, wall_edge = repair_nodes(layout, tri, keep_out)
        if free.shape[1] + wall.shape[1] == 0:
            break
        wall = np.hstack([layout.wall, wall])
        wall_edge = np.concatenate([layout.wall_edge, wall_edge])
        if k < REPAIR_ROUNDS:
            layout = replace(layout, free=np.hstack([layout.free, free]), wall=wall,
                             wall_edge=wall_edge)
            layout = relax(layout, sizing, keep_out, rounds=1)
        else:  # the last resort: where the repair puts them
            layout = replace(layout, fixed=np.hstack([layout.fixed, free]), wall=wall,
                             wall_edge=wall_edge)
        layout, tri = merge_degenerate(layout, sizing)
    return layout, tri


def circumcenters(p: NDArray[np.float64], t: NDArray[np.int64]) -> NDArray[np.float64]:
    """Circumcentres ``(2, T)`` of triangles."""
    a, b, c = p[:, t[0]], p[:, t[1]], p[:, t[2]]
    ba, ca = b - a, c - a
    d = 2.0 * (ba[0] * ca[1] - ba[1] * ca[0])
    nb, nc = np.sum(ba * ba, axis=0), np.sum(ca * ca, axis=0)
    return a + np.vstack([ca[1] * nb - ba[1] * nc, ba[0] * nc - ca[0] * nb]) / d


def repair_nodes(layout: Layout, tri: Triangulation, keep_out: Sequence[NDArray[np.float64]]
                 ) -> tuple[NDArray, NDArray, NDArray]:
    """New nodes for every triangle outside the bounds (in the spirit of Ruppert).

    The circumcentre of a bad triangle is inserted as a free node; if it
    encroaches on a wall segment (lies in its diametral circle) or outside
    the domain, that wall segment is split at its midpoint instead (a new
    sliding wall node). If it lies in or near a particle (whose outline is
    never split), the apex of the equilateral triangle on the bad triangle's
    shortest edge is inserted. Returns ``(free (2, k), wall (2, m), wall_edge
    (m,))``; nearby insertions are thinned to one.
    """
    p, t = tri.points, tri.t
    empty = (np.zeros((2, 0)), np.zeros((2, 0)), np.zeros(0, dtype=np.int64))
    ang, q = angles_and_aspect(p, t)
    bad = (ang.min(axis=0) < SAFE_MIN_ANGLE) | (q > SAFE_MAX_ASPECT)
    if not np.any(bad):
        return empty
    t = t[:, bad]
    L = edge_lengths(p, t)
    size = L.min(axis=0)
    cc = circumcenters(p, t)
    # wall segments encroached on by a circumcentre
    seg, mark = wall_segments(layout)
    A, B = p[:, seg[:, 0]], p[:, seg[:, 1]]
    mid, rad = 0.5 * (A + B), 0.5 * np.hypot(*(B - A))
    dist = np.hypot(cc[0][:, None] - mid[0][None, :], cc[1][:, None] - mid[1][None, :])
    enc = dist < rad[None, :]
    outside = ~inside(layout.domain, cc, 0.0)
    split = np.any(enc, axis=1) | outside
    hit = np.zeros(seg.shape[0], dtype=bool)
    for i in np.flatnonzero(split):
        hit[np.argmin(dist[i] - rad) if not enc[i].any() else np.flatnonzero(enc[i])] = True
    wall = mid[:, hit]
    wall_edge = (mark[hit] - 2).astype(np.int64)
    # circumcentres inside, away from walls and particles
    x = cc[:, ~split]
    gap = 0.5 * size[~split]
    ok = ~near_particles(list(keep_out), x, gap) if keep_out else np.ones(x.shape[1], bool)
    pieces = [x[:, ok]]
    # otherwise the equilateral apex on the shortest edge
    rest = np.flatnonzero(~split)[~ok]
    if rest.size:
        tr = t[:, rest]
        k = np.argmin(L[:, rest], axis=0)
        j = np.arange(rest.size)
        a, b, c = p[:, tr[(k + 1) % 3, j]], p[:, tr[(k + 2) % 3, j]], p[:, tr[k, j]]
        m, e = 0.5 * (a + b), b - a
        nrm = np.vstack([-e[1], e[0]])
        nrm *= np.sign(np.sum(nrm * (c - m), axis=0))
        y = m + 0.5 * np.sqrt(3.0) * nrm
        q = 0.25 * np.hypot(*e)
        good = inside(layout.domain, y, 0.0)
        if keep_out and good.any():
            good[good] &= ~near_particles(list(keep_out), y[:, good], q[good])
        pieces.append(y[:, good])
    free = np.hstack(pieces)
    if free.shape[1] > 1:   # one node per cluster of nearby insertions
        _, first = np.unique(np.round(free / (0.5 * float(size.min()))), axis=1,
                             return_index=True)
        free = free[:, np.sort(first)]
    return free, wall, wall_edge
