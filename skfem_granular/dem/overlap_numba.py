"""Compiled per-pair version of :func:`.overlap.overlap_geometry` (optional numba).

Same algorithm as :mod:`.overlap` (Cyrus-Beck clipping of every edge against
the other polygon, Green's theorem, principal axis of the intersection
points), written as loops over pairs so that numba compiles it. The
vertex-versus-edge-line cross products are computed once per pair
(``na x nb`` each way) and reused by every edge; pairs whose vertex means are
separated along the joining line are rejected first. Pairs run serially: a
``prange`` version was not faster on the shared 2-core machine.
``AVAILABLE`` is False when numba is not installed; callers then use the
numpy version.

numba is imported and the kernels are compiled (:func:`~skfem_granular._jit.lazy_njit`,
``cache=True``: loaded from numba's cache after the first process) at the first
call with at least one pair, not at import: importing numba takes ~0.2 s and
its first compiled call ~0.3 s more, which a scene without candidate pairs
(one particle far from the walls) never needs.
"""

from __future__ import annotations

import importlib.util
import math

import numpy as np

from .._jit import lazy_njit
from .overlap import EPS, EPS_PARALLEL, TAU, OverlapGeometry

AVAILABLE = importlib.util.find_spec("numba") is not None

__all__ = ["AVAILABLE", "overlap_pairs_numba", "pair_overlap", "pair_scratch"]


@lazy_njit
def _clip(S, ns, eS, lS, NS, eC, lC, nc, scale, drop_shared, acc, pts, npts):
    """Clip the edges of S (shifted vertices) against C; accumulate (2A, Mx, My).

    ``NS[k, m]`` is the cross product of C's edge ``m`` with the vector from
    C's vertex ``m`` to S's vertex ``k`` (>= 0: inside that half-plane).
    """
    m0 = 0
    for k in range(ns):
        k1 = (k + 1) % ns
        lo = 0.0
        hi = 1.0
        ok = True
        shared = False
        for j in range(nc):
            # start with the half-plane that cut off the previous edge (often
            # cuts off this one too: early exit)
            m = m0 + j
            if m >= nc:
                m -= nc
            Nn = NS[k, m]
            D = NS[k1, m] - Nn
            tolD = EPS_PARALLEL * lC[m] * lS[k]
            if D > tolD:
                t = -Nn / D
                if t > lo:
                    lo = t
            elif D < -tolD:
                t = -Nn / D
                if t < hi:
                    hi = t
            else:
                tolN = EPS_PARALLEL * lC[m] * scale
                if Nn < -tolN:
                    ok = False
                    m0 = m
                    break
                if (drop_shared and abs(Nn) <= tolN
                        and eC[m, 0] * eS[k, 0] + eC[m, 1] * eS[k, 1] > 0.0):
                    shared = True
            if lo >= hi:
                m0 = m
                break
        if not ok or not hi > lo:
            continue
        p0x = S[k, 0] + lo * eS[k, 0]
        p0y = S[k, 1] + lo * eS[k, 1]
        p1x = S[k, 0] + hi * eS[k, 0]
        p1y = S[k, 1] + hi * eS[k, 1]
        if not shared:
            cr = p0x * p1y - p0y * p1x
            acc[0] += cr
            acc[1] += (p0x + p1x) * cr
            acc[2] += (p0y + p1y) * cr
        if lo > TAU:
            pts[npts, 0] = p0x
            pts[npts, 1] = p0y
            npts += 1
        if hi < 1.0 - TAU:
            pts[npts, 0] = p1x
            pts[npts, 1] = p1y
            npts += 1
    return npts


@lazy_njit
def _edges(S, n, e, el):
    for k in range(n):
        k1 = (k + 1) % n
        e[k, 0] = S[k1, 0] - S[k, 0]
        e[k, 1] = S[k1, 1] - S[k, 1]
        el[k] = math.sqrt(e[k, 0] ** 2 + e[k, 1] ** 2)


@lazy_njit
def _cross_table(S, ns, C, eC, nc, out):
    """out[k, m] = cross(eC[m], S[k] - C[m])."""
    for k in range(ns):
        for m in range(nc):
            out[k, m] = eC[m, 0] * (S[k, 1] - C[m, 1]) - eC[m, 1] * (S[k, 0] - C[m, 0])


@lazy_njit
def _principal_axis(pts, npts, out, p):
    """Direction and extent of the points (written to out[p, 3:6])."""
    mx = 0.0
    my = 0.0
    for q in range(npts):
        mx += pts[q, 0]
        my += pts[q, 1]
    mx /= npts
    my /= npts
    cxx = 0.0
    cyy = 0.0
    cxy = 0.0
    for q in range(npts):
        dx = pts[q, 0] - mx
        dy = pts[q, 1] - my
        cxx += dx * dx
        cyy += dy * dy
        cxy += dx * dy
    th = 0.5 * math.atan2(2.0 * cxy, cxx - cyy)
    u0 = math.cos(th)
    u1 = math.sin(th)
    pmin = math.inf
    pmax = -math.inf
    for q in range(npts):
        s = (pts[q, 0] - mx) * u0 + (pts[q, 1] - my) * u1
        pmin = min(pmin, s)
        pmax = max(pmax, s)
    out[p, 3] = u0
    out[p, 4] = u1
    out[p, 5] = pmax - pmin


@lazy_njit
def pair_overlap(A, na, B, nb, out, p, Sa, Sb, ea, eb, la, lb, NA, NB, acc, pts):
    """Overlap geometry of one pair, written to ``out[p]`` (area, cx, cy, ux, uy, length,
    ncross); ``Sa`` ... ``pts`` are scratch arrays (:func:`pair_scratch`)
    (compiled code only: the compiled substep loop calls it too)."""
    rx = 0.0
    ry = 0.0
    for k in range(na):
        rx += A[k, 0]
        ry += A[k, 1]
    rx /= na
    ry /= na
    bx = 0.0
    by = 0.0
    for k in range(nb):
        bx += B[k, 0]
        by += B[k, 1]
    dx = bx / nb - rx
    dy = by / nb - ry
    # quick rejection: separating axis along the line joining the vertex means
    amax = -math.inf
    for k in range(na):
        amax = max(amax, A[k, 0] * dx + A[k, 1] * dy)
    bmin = math.inf
    for k in range(nb):
        bmin = min(bmin, B[k, 0] * dx + B[k, 1] * dy)
    out[p, 1] = rx
    out[p, 2] = ry
    out[p, 3] = 1.0
    out[p, 4] = 0.0
    out[p, 5] = 0.0
    out[p, 0] = 0.0
    out[p, 6] = 0.0
    if amax < bmin:
        return
    xmin = math.inf
    xmax = -math.inf
    ymin = math.inf
    ymax = -math.inf
    for k in range(na):
        Sa[k, 0] = A[k, 0] - rx
        Sa[k, 1] = A[k, 1] - ry
        xmin = min(xmin, Sa[k, 0])
        xmax = max(xmax, Sa[k, 0])
        ymin = min(ymin, Sa[k, 1])
        ymax = max(ymax, Sa[k, 1])
    sa = max(xmax - xmin, ymax - ymin)
    xmin = math.inf
    xmax = -math.inf
    ymin = math.inf
    ymax = -math.inf
    for k in range(nb):
        Sb[k, 0] = B[k, 0] - rx
        Sb[k, 1] = B[k, 1] - ry
        xmin = min(xmin, Sb[k, 0])
        xmax = max(xmax, Sb[k, 0])
        ymin = min(ymin, Sb[k, 1])
        ymax = max(ymax, Sb[k, 1])
    scale = max(sa, max(xmax - xmin, ymax - ymin))
    _edges(Sa, na, ea, la)
    _edges(Sb, nb, eb, lb)
    _cross_table(Sa, na, Sb, eb, nb, NA)
    _cross_table(Sb, nb, Sa, ea, na, NB)
    acc[0] = 0.0
    acc[1] = 0.0
    acc[2] = 0.0
    npts = _clip(Sa, na, ea, la, NA, eb, lb, nb, scale, False, acc, pts, 0)
    npts = _clip(Sb, nb, eb, lb, NB, ea, la, na, scale, True, acc, pts, npts)
    a = 0.5 * acc[0]
    if a > (EPS * scale) ** 2:
        out[p, 0] = a
        out[p, 1] = acc[1] / (3.0 * acc[0]) + rx
        out[p, 2] = acc[2] / (3.0 * acc[0]) + ry
    out[p, 6] = npts
    if npts >= 2:
        _principal_axis(pts, npts, out, p)


@lazy_njit
def pair_scratch(nmax):
    """The scratch arrays of :func:`pair_overlap` for outlines of up to ``nmax`` vertices:
    ``(Sa, Sb, ea, eb, la, lb, NA, NB, acc, pts)``."""
    return (np.empty((nmax, 2)), np.empty((nmax, 2)), np.empty((nmax, 2)),
            np.empty((nmax, 2)), np.empty(nmax), np.empty(nmax), np.empty((nmax, nmax)),
            np.empty((nmax, nmax)), np.empty(3), np.empty((4 * nmax + 4, 2)))


@lazy_njit
def _kernel(V, count, I, J, out):
    """out[p] = (area, cx, cy, ux, uy, length, ncross) for every pair p."""
    Sa, Sb, ea, eb, la, lb, NA, NB, acc, pts = pair_scratch(V.shape[1])  # allocated once
    for p in range(I.shape[0]):
        pair_overlap(V[I[p]], count[I[p]], V[J[p]], count[J[p]], out, p,
                     Sa, Sb, ea, eb, la, lb, NA, NB, acc, pts)


def overlap_pairs_numba(V: np.ndarray, count: np.ndarray, I: np.ndarray, J: np.ndarray):
    """Overlap geometry of bodies ``I[p]`` and ``J[p]`` (compiled).

    Parameters
    ----------
    V
        ``(Nb, nmax, 2)`` padded world vertices of all bodies.
    count
        ``(Nb,)`` true vertex counts.
    I, J
        ``int64`` pair indices.

    Returns
    -------
    OverlapGeometry
    """
    out = np.empty((I.shape[0], 7))
    if I.shape[0]:
        _kernel(np.ascontiguousarray(V), count, I, J, out)
    return OverlapGeometry(out[:, 0].copy(), out[:, 1:3].T.copy(), out[:, 3:5].T.copy(),
                           out[:, 5].copy(), out[:, 6].astype(np.int64))
