"""What collapse experiments report, measured on the grains of a run.

All functions take plain arrays (a history row's positions, or a live DEM's): grain
outlines ``(2, k)``, centroid positions and velocities ``(2, N)``. Lengths in metres;
normalise with the packing's ``L0``, ``H0`` and ``tau_c = sqrt(H0 / g)``.

- :func:`front_position`: the run-out ``L(t)``: the right end of the grains connected
  to the left wall (gaps wider than ``gap`` cut off grains thrown ahead);
- :func:`mass_front`: the deposit's front: the farthest grain in contact with the
  main mass (the largest group of grains touching each other);
- :func:`deposit_profile`, :func:`height_at`: the free surface ``h(x)`` (the upper
  boundary of the grains);
- :func:`kinetic_energies`: horizontal, vertical and rotational kinetic energy;
- :func:`front_froude`: ``Fr = (dL/dt) / sqrt(g H0)``; :func:`front_vertex` and
  :func:`front_speed`: the point at the front and its speed (no jumps where the
  front passes to another grain);
- :func:`flowing_solid_fraction`: grain area over hull area of the moving grains.
"""

from __future__ import annotations

import numpy as np

from ..dem import Polygon
from ..dem.polygon import polygon_area, polygon_properties
from ..packing import Packing

__all__ = ["deposit_profile", "flowing_solid_fraction", "front_froude", "front_position",
           "front_speed", "front_vertex",
           "grain_outlines", "height_at", "kinetic_energies", "local_outlines", "masses",
           "mass_front", "normalised_runout", "realisations"]


def local_outlines(packing: Packing) -> tuple[list[np.ndarray], np.ndarray]:
    """The grains' outlines relative to their centroids (angle 0) and the centroids (2, N)."""
    C = np.column_stack([Polygon(P).centroid for P in packing.outlines])
    return [P - C[:, [k]] for k, P in enumerate(packing.outlines)], C


def masses(packing: Packing) -> tuple[np.ndarray, np.ndarray]:
    """Mass and moment of inertia per unit length ``(N,)`` of the packing's grains."""
    props = [polygon_properties(np.asarray(P)) for P in packing.outlines]
    A = np.array([p[0] for p in props])
    J = np.array([p[2] for p in props])
    return packing.density * A, packing.density * J


def grain_outlines(local, x, y, angle) -> list[np.ndarray]:
    """World outlines of grains with local outlines ``local`` at poses ``(x, y, angle)``."""
    out = []
    for k, P in enumerate(local):
        c, s = np.cos(angle[k]), np.sin(angle[k])
        out.append(np.array([[c, -s], [s, c]]) @ P + np.array([[x[k]], [y[k]]]))
    return out


def front_position(outlines, x_wall: float = 0.0, gap: float | None = None) -> float:
    """Right end of the grains connected to the left wall along ``x``.

    The grains' ``x`` extents are merged from ``x_wall`` rightwards; a hole wider than
    ``gap`` (default: the largest grain's width) ends the mass, so grains thrown
    ahead of it do not count.
    """
    return front_vertex(outlines, x_wall, gap)[0]


def front_vertex(outlines, x_wall: float = 0.0,
                 gap: float | None = None) -> tuple[float, int, int]:
    """:func:`front_position` and the point that sets it.

    Returns
    -------
    position : float
        The front ``L`` (``x_wall`` when no grain reaches the wall's mass).
    grain, vertex : int
        The grain and the vertex of its outline at the front (``-1, -1`` when none).
    """
    lo = np.array([P[0].min() for P in outlines])
    hi = np.array([P[0].max() for P in outlines])
    if gap is None:
        gap = float((hi - lo).max())
    end, grain = x_wall, -1
    for k in np.argsort(lo):
        if lo[k] > end + gap:
            break
        if hi[k] > end:
            end, grain = float(hi[k]), int(k)
    vertex = int(np.argmax(outlines[grain][0])) if grain >= 0 else -1
    return end, grain, vertex


def front_speed(outlines, grain: int, vertex: int, centroids, velocities,
                omegas) -> float:
    """Horizontal speed of the front's point, ``vx - omega (y_p - y_c)`` of its grain.

    The rate ``dL/dt`` of :func:`front_froude` jumps where the front passes from one
    grain to another (a grain joining or leaving the mass); the speed of the grain
    material at the front does not, and equals ``dL/dt`` while the front stays on
    one vertex. ``centroids`` and ``velocities`` are ``(2, N)``, ``omegas`` ``(N,)``;
    0 when there is no front (``grain < 0``).
    """
    if grain < 0:
        return 0.0
    y_p = outlines[grain][1, vertex]
    return float(velocities[0][grain] - omegas[grain] * (y_p - centroids[1][grain]))


def _separation(P: np.ndarray, Q: np.ndarray) -> float:
    """Largest gap between convex outlines ``P`` and ``Q`` along their edge normals
    (separating axes): ``> 0`` apart, ``<= 0`` touching or overlapping."""
    gap = -np.inf
    for A, B in ((P, Q), (Q, P)):
        e = np.roll(A, -1, axis=1) - A
        n = np.vstack([e[1], -e[0]]) / np.hypot(e[0], e[1])  # outward (counter-clockwise)
        gap = max(gap, float(((n.T @ B).min(axis=1) - (n.T @ A).max(axis=1)).max()))
    return gap


def mass_front(outlines, tol: float | None = None) -> float:
    """Right end of the grains in contact with the main mass (the deposit's front).

    Grains touching each other (separating-axis gap below ``tol``) form groups; the
    main mass is the largest group by area, and the front is its rightmost point.
    This is Kumar's (2015, PhD thesis, Cambridge, ch. 4) run-out of 2D DEM collapses,
    "the farthest grain which has at least one contact with the main mass": grains
    rolling ahead alone, or resting on the floor a hair's breadth apart, do not count.

    Parameters
    ----------
    outlines : sequence of (2, k) arrays
        Convex, counter-clockwise grain outlines.
    tol : float, optional
        Largest gap still counted as a contact (default: 1 % of the smallest grain's
        width; grains at rest overlap, by the soft contact law).
    """
    P = [np.asarray(p, dtype=float) for p in outlines]
    lo = np.array([[p[0].min(), p[1].min()] for p in P])
    hi = np.array([[p[0].max(), p[1].max()] for p in P])
    if tol is None:
        tol = 0.01 * float((hi - lo)[:, 0].min())
    near = np.all((lo[:, None, :] <= hi[None, :, :] + tol)
                  & (lo[None, :, :] <= hi[:, None, :] + tol), axis=2)
    parent = list(range(len(P)))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i, j in zip(*np.nonzero(np.triu(near, 1)), strict=True):
        if root(i) != root(j) and _separation(P[i], P[j]) <= tol:
            parent[root(i)] = root(j)
    roots = np.array([root(k) for k in range(len(P))])
    area = np.array([0.5 * float(np.dot(p[0], np.roll(p[1], -1))
                                 - np.dot(np.roll(p[0], -1), p[1])) for p in P])
    groups = np.unique(roots)
    main = groups[np.argmax([area[roots == g].sum() for g in groups])]
    return float(hi[roots == main, 0].max())


def _top(P: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Upper boundary of the convex outline ``P`` at abscissae ``x`` (``-inf`` off it)."""
    xa, ya = P
    xb, yb = np.roll(xa, -1), np.roll(ya, -1)
    lo, hi = np.minimum(xa, xb), np.maximum(xa, xb)
    X = x[:, None]
    on = (X >= lo) & (X <= hi) & (hi > lo)
    t = np.where(on, (X - xa) / np.where(hi > lo, xb - xa, 1.0), 0.0)
    y = np.where(on, ya + t * (yb - ya), -np.inf)
    return y.max(axis=1)


def deposit_profile(outlines, x) -> np.ndarray:
    """Height of the free surface at the abscissae ``x``: the highest grain boundary above
    each point (0, the floor, where no grain is above it)."""
    x = np.asarray(x, dtype=float)
    h = np.zeros(x.size)
    for P in outlines:
        P = np.asarray(P)
        sel = (x >= P[0].min()) & (x <= P[0].max())
        if sel.any():
            h[sel] = np.maximum(h[sel], _top(P, x[sel]))
    return h


def height_at(outlines, x: float, width: float) -> float:
    """Highest free-surface point over ``[x - width / 2, x + width / 2]`` (e.g. at the gate)."""
    return float(deposit_profile(outlines, np.linspace(x - width / 2, x + width / 2, 11)).max())


def kinetic_energies(mass, inertia, velocities, omega) -> tuple[float, float, float]:
    """``(E_x, E_y, E_rot)``: ``sum m vx^2 / 2``, ``sum m vy^2 / 2``, ``sum I w^2 / 2``."""
    v = np.asarray(velocities)
    return (float(0.5 * (mass * v[0] ** 2).sum()), float(0.5 * (mass * v[1] ** 2).sum()),
            float(0.5 * (inertia * np.asarray(omega) ** 2).sum()))


def normalised_runout(front, L0: float) -> np.ndarray:
    """``(L - L0) / L0``."""
    return (np.asarray(front, dtype=float) - L0) / L0


def front_froude(t, front, H0: float, gravity: float = 9.81) -> np.ndarray:
    """``Fr = U_f / sqrt(g H0)`` with ``U_f = dL/dt`` (second-order differences)."""
    t, front = np.asarray(t, dtype=float), np.asarray(front, dtype=float)
    return np.gradient(front, t) / np.sqrt(gravity * H0)


def flowing_solid_fraction(outlines, speeds, v_min: float) -> float:
    """Area of the grains faster than ``v_min`` over the area of their convex hull.

    The hull of a flowing layer over-counts the empty corners of a curved surface, so
    this is a lower estimate; ``nan`` with fewer than three moving grains.
    """
    from scipy.spatial import ConvexHull  # scipy.spatial: imported when used

    moving = [P for P, s in zip(outlines, speeds, strict=True) if s > v_min]
    if len(moving) < 3:
        return float("nan")
    V = np.concatenate(moving, axis=1)
    A = sum(polygon_area(P) for P in moving)
    return A / ConvexHull(V.T).volume


def realisations(values) -> dict:
    """A quantity over realisations (seeds) of a chaotic run: ``mean``, ``std`` (sample
    standard deviation, None for one value), ``min``, ``max`` and ``count``."""
    v = np.asarray(values, dtype=float)
    if v.ndim != 1 or v.size == 0:
        raise ValueError(f"values: shape {v.shape}; expected one value per realisation")
    return {"mean": float(v.mean()), "std": float(v.std(ddof=1)) if v.size > 1 else None,
            "min": float(v.min()), "max": float(v.max()), "count": int(v.size)}
