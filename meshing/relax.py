"""Spring relaxation of a triangulation towards equilateral triangles.

Every edge is a linear spring whose rest length is the target size ``h`` at
its midpoint, scaled so that the rest lengths fill the domain with the nodes
present (sum of squared rest lengths equals sum of squared lengths). Nodes
move along the net spring force (explicit pseudo-time steps); free nodes move
freely but never closer than a fraction of ``h`` to the domain outline or a
keep-out polygon, wall nodes slide along their edge without passing their
neighbours, corners, particle and other fixed nodes stay. The triangulation is
rebuilt between rounds, so edges reconnect towards nearer nodes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from .cleanup import SizeRule, near_particles
from .pslg import Layout, triangulate

KEEP_OUT = 0.3
"""Free nodes stay at least this times ``h`` away from walls and keep-out polygons."""


def unique_edges(t: NDArray[np.int64]) -> NDArray[np.int64]:
    """Unique undirected edges ``(2, E)`` of triangles ``(3, T)``."""
    e = np.sort(np.hstack([t[[0, 1]], t[[1, 2]], t[[2, 0]]]), axis=0)
    n = int(t.max()) + 1
    key = np.unique(e[0] * n + e[1])
    return np.vstack([key // n, key % n])


def spring_forces(x: NDArray[np.float64], e: NDArray[np.int64],
                  sizing: SizeRule) -> NDArray[np.float64]:
    """Net spring force per node ``(2, n)`` (in units of length)."""
    d = x[:, e[1]] - x[:, e[0]]
    L = np.hypot(*d)
    L0 = sizing(0.5 * (x[:, e[0]] + x[:, e[1]]))
    L0 *= np.sqrt(np.sum(L * L) / np.sum(L0 * L0))
    f = (L - L0) / np.maximum(L, 1e-300) * d
    n = x.shape[1]
    F = np.empty_like(x)
    for c in range(2):
        F[c] = np.bincount(e[0], f[c], n) - np.bincount(e[1], f[c], n)
    return F


def relax(layout: Layout, sizing: SizeRule, keep_out: Sequence[NDArray[np.float64]] = (),
          rounds: int = 4, steps: int = 8, dt: float = 0.15) -> Layout:
    """Relax a layout's free and wall nodes (see module docstring).

    Parameters
    ----------
    layout
        Nodes to relax; corners, particles and ``fixed`` nodes stay.
    sizing
        Target size field.
    keep_out
        Convex ccw polygons free nodes must stay outside of (particles, or a
        group's fine region).
    rounds, steps
        Re-triangulations, and pseudo-time steps per triangulation.
    dt
        Step size (fraction of the net spring force applied per step).
    """
    D = layout.domain
    nd, nw, nf = layout.n_wall_frozen, layout.n_wall, layout.n_frozen
    edge_dir = np.roll(D, -1, axis=1) - D
    edge_len = np.hypot(*edge_dir)
    edge_dir = edge_dir / edge_len
    wall_e = layout.wall_edge
    nc = layout.n_corners
    for _ in range(rounds):
        tri = triangulate(layout)
        e = unique_edges(tri.t)
        x = tri.points.copy()
        s_all = np.sum((x[:, :nw] - D[:, wall_e]) * edge_dir[:, wall_e], axis=0)
        s_all[:nc] = 0.0
        order = np.lexsort((s_all, wall_e))     # stays valid: nodes never pass
        for _ in range(steps):
            F = dt * spring_forces(x, e, sizing)
            # free nodes: limited step, rejected if it leaves the allowed region
            xf = x[:, nf:]
            h = sizing(xf)
            step = F[:, nf:]
            norm = np.hypot(*step)
            step *= np.minimum(1.0, 0.2 * h / np.maximum(norm, 1e-300))
            trial = xf + step
            ok = _wall_clear(D, trial, KEEP_OUT * h)
            if keep_out:
                ok &= ~near_particles(keep_out, trial, KEEP_OUT * h)
            xf[:, ok] = trial[:, ok]
            # wall nodes slide along their edge, never past a neighbour
            if nw > nd:
                s = s_all[nd:]
                ds = np.sum(F[:, nd:nw] * edge_dir[:, wall_e[nd:]], axis=0)
                gap = _neighbour_gap(s_all, wall_e, edge_len, order)[nd:]
                s_all[nd:] = s + np.clip(ds, -0.3 * gap, 0.3 * gap)
                x[:, nd:nw] = D[:, wall_e[nd:]] + s_all[nd:] * edge_dir[:, wall_e[nd:]]
        layout = replace(layout, wall=x[:, :nw], free=x[:, nf:])
    return layout


def _wall_clear(D: NDArray[np.float64], x: NDArray[np.float64],
                gap: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Points at least ``gap`` inside every edge line of a convex outline."""
    A = D[:, :, None]
    E = np.roll(D, -1, axis=1)[:, :, None] - A
    L = np.hypot(*E)
    R = x[:, None, :] - A
    return np.all((E[0] * R[1] - E[1] * R[0]) / L > gap[None, :], axis=0)


def _neighbour_gap(s: NDArray[np.float64], edge: NDArray[np.int64],
                   edge_len: NDArray[np.float64], order: NDArray[np.int64]) -> NDArray[np.float64]:
    """Distance of each wall node to its nearer neighbour on the same edge
    (the edge's end corner counts); ``order`` sorts nodes by edge, then ``s``."""
    pos, ed = s[order], edge[order]
    prev = np.empty_like(pos)
    nxt = np.empty_like(pos)
    prev[0] = pos[0]
    prev[1:] = np.where(ed[1:] == ed[:-1], pos[1:] - pos[:-1], pos[1:])
    nxt[-1] = edge_len[ed[-1]] - pos[-1]
    nxt[:-1] = np.where(ed[:-1] == ed[1:], pos[1:] - pos[:-1], edge_len[ed[:-1]] - pos[:-1])
    gap = np.empty_like(s)
    gap[order] = np.minimum(prev, nxt)
    return gap
