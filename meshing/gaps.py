"""Outline edges facing a narrow gap, split so that the flow in the gap is resolved.

A gap ``g`` between two outlines (or an outline and a wall) narrower than
:data:`GAP_NARROW` outline edges is lined with outline nodes at most
:data:`GAP_SPACING` ``g`` apart: :func:`split_gap_edges` adds nodes on the
straight outline edges, graded along each edge with the local gap (the node
count on an edge is the integral of ``1 / h`` along it, ``h = min(L, g / 3)``,
nodes equidistant in that integral, as on the walls). Every outline vertex
stays, in order; the polygon is the same. The first layer and the fill then
put about three elements across the gap (measured in docs/meshing.md: the
pore flux of a touching honeycomb within 0.53 % of a converged reference,
5.9 % with the outline edges alone).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .geometry import edge_distance

if TYPE_CHECKING:
    from .size_field import SizeField

GAP_SPACING = 1.0 / 3.0
"""Outline spacing along a narrow gap, as a fraction of its width (three outline
edges per gap width; ``1 / sqrt(3)``, equilateral triangles of half the gap's
height, leaves the pore flux of the touching honeycomb 0.95 % off, docs/meshing.md)."""

GAP_NARROW = 2.0
"""Gaps narrower than this many outline edge lengths (the particle's mean) are
narrow: the outline edges facing them are split."""

SAMPLES = 9
"""Points per edge at which the gap is measured (ends included)."""


def gap_width(D: NDArray[np.float64], field: SizeField, x: NDArray[np.float64],
              own: NDArray[np.int64]) -> NDArray[np.float64]:
    """Distance ``(M,)`` from points ``x`` on outline ``own`` to the nearest other
    outline (among the particles :meth:`SizeField.nearest` searches) or the wall."""
    d, idx = field.nearest(x)
    d = np.where(idx == own[:, None], np.inf, d).min(axis=1)
    return np.minimum(d, np.maximum(edge_distance(D, x)[0], 0.0))


def split_gap_edges(D: NDArray[np.float64], outlines: list[NDArray[np.float64]],
                    field: SizeField, spacing: float = GAP_SPACING
                    ) -> tuple[list[NDArray[np.float64]], list[NDArray[np.int64]]]:
    """Outlines with the edges that face a narrow gap split (module notes).

    Parameters
    ----------
    D
        Domain outline ``(2, n)``.
    outlines
        Particle outlines ``(2, N_k)`` (subdivided).
    field
        The size field of the mesh (its distance queries).
    spacing
        Node spacing along a gap as a fraction of its width.

    Returns
    -------
    outlines, vertices
        The split outlines and, per outline, the positions of its original
        vertices in the split one (increasing).
    """
    if not outlines:
        return [], []
    counts = np.array([P.shape[1] for P in outlines])
    P = np.hstack(outlines)
    own = np.repeat(np.arange(len(outlines)), counts)
    first = np.cumsum(counts) - counts
    nxt = np.arange(P.shape[1]) + 1
    nxt[first + counts - 1] = first
    Q = P[:, nxt]
    L = np.hypot(*(Q - P))
    narrow = GAP_NARROW * field.dl[own]
    # the gap is 1-Lipschitz along an edge: only edges near another outline can split
    g_mid = gap_width(D, field, 0.5 * (P + Q), own)
    cand = np.flatnonzero(g_mid - 0.5 * L < np.minimum(L / spacing, narrow))
    m = np.ones(P.shape[1], dtype=np.int64)
    pos: list[NDArray] = []
    if cand.size:
        s = np.linspace(0.0, 1.0, SAMPLES)
        X = (P[:, cand, None] + (Q - P)[:, cand, None] * s).reshape(2, -1)
        g = gap_width(D, field, X, np.repeat(own[cand], SAMPLES)).reshape(cand.size, SAMPLES)
        Lc = L[cand, None]
        h = np.minimum(Lc, spacing * np.maximum(g, 1e-3 * Lc))
        h = np.where(g < narrow[cand, None], h, Lc)
        inv = 1.0 / h
        F = np.concatenate([np.zeros((cand.size, 1)), np.cumsum(
            0.5 * (inv[:, 1:] + inv[:, :-1]) * np.diff(s) * Lc, axis=1)], axis=1)
        m[cand] = np.maximum(1, np.ceil(F[:, -1] - 1e-6)).astype(np.int64)
        split = m[cand] > 1
        cand, F = cand[split], F[split]
        pos = [np.interp(np.arange(1, m[k]) * (f[-1] / m[k]), f, s) for k, f in zip(cand, F,
                                                                                      strict=True)]
    # node j of the split outlines: edge e[j] at parameter t[j]
    start = np.cumsum(m) - m
    e = np.repeat(np.arange(P.shape[1]), m)
    t = np.zeros(e.size)
    for k, ts in zip(cand if pos else [], pos, strict=True):
        t[start[k] + 1:start[k] + m[k]] = ts
    X = P[:, e] + (Q - P)[:, e] * t
    n_new = np.add.reduceat(m, first)
    off = np.cumsum(n_new) - n_new
    out = [X[:, a:a + n] for a, n in zip(off, n_new, strict=True)]
    where = [start[a:a + c] - o for a, c, o in zip(first, counts, off, strict=True)]
    # untouched outlines stay the very same arrays
    out = [Pk if n == c else O for O, n, c, Pk in zip(out, n_new, counts, outlines,
                                                         strict=True)]
    return out, where
