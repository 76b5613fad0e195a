"""Contact geometry: overlap of two convex polygons, vectorised over pairs.

The overlap polygon of two convex polygons is bounded by the parts of the
edges of each polygon that lie inside the other. Each edge is clipped
against the other polygon's half-planes (Cyrus-Beck), and area and centroid
follow from Green's theorem over the clipped segments, with no sorting of
vertices. Endpoints of clipped segments that are interior to an edge are the
*intersection points of the outlines*; the contact normal is perpendicular to
the line through them (their principal axis when more than two coincide, as
for collinear edges).

The same algorithm is compiled per pair by :mod:`.overlap_numba` when numba
is available; this module is the reference implementation.
"""

from __future__ import annotations

import numpy as np

__all__ = ["OverlapGeometry", "contact_normals", "overlap_geometry"]

#: relative tolerance for parallel edges and points on an edge line
EPS = 1e-12
#: edges closer than this (relative) to parallel and collinear are treated as
#: exactly collinear, so that aligned faces (a square on a floor) give a
#: well-defined chord even after round-off has rotated them slightly
EPS_PARALLEL = 1e-9
#: a clipped-segment end within this parameter distance of an edge end is a
#: vertex, not a crossing (the crossing is then found from the other outline)
TAU = 1e-9


class OverlapGeometry:
    """Result of :func:`overlap_geometry` (all arrays over pairs ``P``).

    Attributes
    ----------
    area
        ``(P,)`` overlap area (0 when the polygons are apart or touch).
    centroid
        ``(2, P)`` overlap centroid (point of action; undefined where area = 0).
    chord
        ``(2, P)`` unit direction of the line through the intersection points.
    length
        ``(P,)`` distance between the extreme intersection points (chord length).
    ncross
        ``(P,)`` number of intersection points found, each crossing counted
        once from each outline (4 in the generic case of two crossings).
    """

    def __init__(self, area, centroid, chord, length, ncross):
        self.area = area
        self.centroid = centroid
        self.chord = chord
        self.length = length
        self.ncross = ncross


def _clip_edges(S, C, scale, drop_shared):
    """Clip every edge of ``S`` against convex ``C``; return segments and crossings."""
    a = S
    e = np.roll(S, -1, axis=1) - S
    b = C
    f = np.roll(C, -1, axis=1) - C
    fx, fy = f[:, None, :, 0], f[:, None, :, 1]
    ex, ey = e[:, :, None, 0], e[:, :, None, 1]
    Nn = fx * (a[:, :, None, 1] - b[:, None, :, 1]) - fy * (a[:, :, None, 0] - b[:, None, :, 0])
    # D = cross(f, e) written as the change of Nn along the edge (same as the
    # compiled kernel, so both backends agree to the last bit in degenerate cases)
    D = np.roll(Nn, -1, axis=1) - Nn
    flen = np.hypot(fx, fy)
    elen = np.hypot(ex, ey)
    tolD = EPS_PARALLEL * flen * elen
    tolN = EPS_PARALLEL * flen * scale[:, None, None]
    par = np.abs(D) <= tolD
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -Nn / D
    lo = np.where(D > tolD, t, -np.inf).max(axis=2)
    hi = np.where(D < -tolD, t, np.inf).min(axis=2)
    lo = np.maximum(lo, 0.0)
    hi = np.minimum(hi, 1.0)
    outside = np.any(par & (Nn < -tolN), axis=2)
    valid = (hi > lo) & ~outside
    P0 = a + lo[..., None] * e
    P1 = a + hi[..., None] * e
    c0 = valid & (lo > TAU)
    c1 = valid & (hi < 1.0 - TAU)
    w = valid
    if drop_shared:
        same = par & (np.abs(Nn) <= tolN) & (fx * ex + fy * ey > 0.0)
        w = valid & ~np.any(same, axis=2)
    cr = P0[..., 0] * P1[..., 1] - P0[..., 1] * P1[..., 0]
    cr = np.where(w, cr, 0.0)
    A2 = cr.sum(axis=1)
    Mx = ((P0[..., 0] + P1[..., 0]) * cr).sum(axis=1)
    My = ((P0[..., 1] + P1[..., 1]) * cr).sum(axis=1)
    pts = np.concatenate([P0, P1], axis=1)
    mask = np.concatenate([c0, c1], axis=1)
    return A2, Mx, My, pts, mask


def overlap_geometry(VA: np.ndarray, VB: np.ndarray) -> OverlapGeometry:
    """Overlap of convex polygons ``VA[p]`` and ``VB[p]`` for every pair ``p``.

    Parameters
    ----------
    VA, VB
        ``(P, na, 2)`` and ``(P, nb, 2)`` counter-clockwise vertices, padded by
        repeating the first vertex (zero-length edges are ignored).

    Returns
    -------
    OverlapGeometry
    """
    P = VA.shape[0]
    ref = VA.mean(axis=1)  # shift to reduce round-off
    A = VA - ref[:, None, :]
    B = VB - ref[:, None, :]
    scale = np.maximum(np.ptp(A, axis=1).max(axis=1), np.ptp(B, axis=1).max(axis=1))
    a2, mx, my, pa, ma = _clip_edges(A, B, scale, drop_shared=False)
    b2, nx, ny, pb, mb = _clip_edges(B, A, scale, drop_shared=True)
    A2 = a2 + b2
    area = 0.5 * A2
    pos = area > (EPS * scale) ** 2
    area = np.where(pos, area, 0.0)
    den = np.where(pos, 3.0 * A2, 1.0)
    centroid = np.vstack([(mx + nx) / den + ref[:, 0], (my + ny) / den + ref[:, 1]])
    pts = np.concatenate([pa, pb], axis=1)
    mask = np.concatenate([ma, mb], axis=1)
    chord, length, ncross = _principal_axis(pts, mask)
    chord = chord if P else np.zeros((2, 0))
    return OverlapGeometry(area, centroid, chord, length, ncross)


def _principal_axis(pts, mask):
    """Principal direction and extent of the masked points of every pair."""
    w = mask.astype(float)
    k = w.sum(axis=1)
    kk = np.maximum(k, 1.0)
    m = (pts * w[..., None]).sum(axis=1) / kk[:, None]
    d = (pts - m[:, None, :]) * w[..., None]
    cxx = (d[..., 0] ** 2).sum(axis=1)
    cyy = (d[..., 1] ** 2).sum(axis=1)
    cxy = (d[..., 0] * d[..., 1]).sum(axis=1)
    th = 0.5 * np.arctan2(2.0 * cxy, cxx - cyy)
    u = np.vstack([np.cos(th), np.sin(th)])
    proj = d[..., 0] * u[0][:, None] + d[..., 1] * u[1][:, None]
    length = np.where(
        k >= 2,
        np.where(mask, proj, -np.inf).max(axis=1, initial=-np.inf)
        - np.where(mask, proj, np.inf).min(axis=1, initial=np.inf),
        0.0,
    )
    return u, length, k.astype(np.int64)


def contact_normals(geom: OverlapGeometry, Xi: np.ndarray, Xj: np.ndarray) -> np.ndarray:
    """Unit normals ``(2, P)`` pointing from body ``i`` towards body ``j``.

    Perpendicular to the chord through the intersection points, oriented so
    that it points from centroid ``Xi`` to the overlap centroid. With fewer
    than two intersection points (one polygon inside the other) or a
    vanishing chord, the direction from ``Xi`` to the overlap centroid is used
    (and ``Xj - Xi`` if that vanishes too).
    """
    n = np.vstack([-geom.chord[1], geom.chord[0]])
    r = geom.centroid - Xi
    s = np.sign((n * r).sum(axis=0))
    n = n * np.where(s == 0.0, 1.0, s)
    bad = (geom.ncross < 2) | (geom.length <= 0.0)  # no chord: containment
    if np.any(bad):
        alt = np.where((r * r).sum(axis=0) > 0.0, r, Xj - Xi)
        alt = alt / np.maximum(np.hypot(alt[0], alt[1]), 1e-300)
        n = np.where(bad, alt, n)
    return n
