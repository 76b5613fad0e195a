"""Compiled per-pair version of :func:`.overlap.overlap_geometry` (optional numba).

Same algorithm as :mod:`.overlap` (Cyrus-Beck clipping of every edge against
the other polygon, Green's theorem, principal axis of the intersection
points), written as loops over pairs so that numba compiles it. ``AVAILABLE``
is False when numba is not installed; callers then use the numpy version.
"""

from __future__ import annotations

import math

import numpy as np

from .overlap import EPS, EPS_PARALLEL, TAU, OverlapGeometry

try:  # pragma: no cover - depends on the environment
    import numba

    AVAILABLE = True
except ImportError:  # pragma: no cover
    numba = None
    AVAILABLE = False

__all__ = ["AVAILABLE", "overlap_pairs_numba"]


def _clip(S, ns, C, nc, rx, ry, scale, drop_shared, acc, pts, npts):
    """Clip the edges of S against C; accumulate (2A, Mx, My) into acc."""
    for k in range(ns):
        k1 = (k + 1) % ns
        ax = S[k, 0] - rx
        ay = S[k, 1] - ry
        ex = S[k1, 0] - S[k, 0]
        ey = S[k1, 1] - S[k, 1]
        elen = math.sqrt(ex * ex + ey * ey)
        lo = 0.0
        hi = 1.0
        ok = True
        shared = False
        for m in range(nc):
            m1 = (m + 1) % nc
            bx = C[m, 0] - rx
            by = C[m, 1] - ry
            fx = C[m1, 0] - C[m, 0]
            fy = C[m1, 1] - C[m, 1]
            flen = math.sqrt(fx * fx + fy * fy)
            Nn = fx * (ay - by) - fy * (ax - bx)
            D = fx * ey - fy * ex
            tolD = EPS_PARALLEL * flen * elen
            tolN = EPS_PARALLEL * flen * scale
            if D > tolD:
                t = -Nn / D
                if t > lo:
                    lo = t
            elif D < -tolD:
                t = -Nn / D
                if t < hi:
                    hi = t
            else:
                if Nn < -tolN:
                    ok = False
                    break
                if drop_shared and abs(Nn) <= tolN and fx * ex + fy * ey > 0.0:
                    shared = True
            if lo >= hi:
                break
        if not ok or not hi > lo:
            continue
        p0x = ax + lo * ex
        p0y = ay + lo * ey
        p1x = ax + hi * ex
        p1y = ay + hi * ey
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


def _kernel(V, count, I, J, area, cx, cy, ux, uy, length, ncross):
    nmax = V.shape[1]
    pts = np.empty((4 * nmax + 4, 2))
    acc = np.empty(3)
    for p in range(I.shape[0]):
        A = V[I[p]]
        B = V[J[p]]
        na = count[I[p]]
        nb = count[J[p]]
        rx = 0.0
        ry = 0.0
        for k in range(na):
            rx += A[k, 0]
            ry += A[k, 1]
        rx /= na
        ry /= na
        xmin = xmax = A[0, 0]
        ymin = ymax = A[0, 1]
        for k in range(na):
            xmin = min(xmin, A[k, 0])
            xmax = max(xmax, A[k, 0])
            ymin = min(ymin, A[k, 1])
            ymax = max(ymax, A[k, 1])
        sa = max(xmax - xmin, ymax - ymin)
        xmin = xmax = B[0, 0]
        ymin = ymax = B[0, 1]
        for k in range(nb):
            xmin = min(xmin, B[k, 0])
            xmax = max(xmax, B[k, 0])
            ymin = min(ymin, B[k, 1])
            ymax = max(ymax, B[k, 1])
        scale = max(sa, max(xmax - xmin, ymax - ymin))
        acc[:] = 0.0
        npts = _clip(A, na, B, nb, rx, ry, scale, False, acc, pts, 0)
        npts = _clip(B, nb, A, na, rx, ry, scale, True, acc, pts, npts)
        a = 0.5 * acc[0]
        if a > (EPS * scale) ** 2:
            area[p] = a
            cx[p] = acc[1] / (3.0 * acc[0]) + rx
            cy[p] = acc[2] / (3.0 * acc[0]) + ry
        else:
            area[p] = 0.0
            cx[p] = rx
            cy[p] = ry
        ncross[p] = npts
        if npts >= 2:
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
            ux[p] = u0
            uy[p] = u1
            length[p] = pmax - pmin
        else:
            ux[p] = 1.0
            uy[p] = 0.0
            length[p] = 0.0


if AVAILABLE:  # pragma: no branch
    _clip = numba.njit(cache=True, fastmath=False)(_clip)
    _kernel = numba.njit(cache=True, fastmath=False)(_kernel)


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
    P = I.shape[0]
    area, cx, cy, ux, uy, length = (np.empty(P) for _ in range(6))
    ncross = np.empty(P, dtype=np.int64)
    _kernel(np.ascontiguousarray(V), count, I, J, area, cx, cy, ux, uy, length, ncross)
    return OverlapGeometry(area, np.vstack([cx, cy]), np.vstack([ux, uy]), length, ncross)
