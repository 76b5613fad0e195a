"""What collapse experiments report, measured on the grains of a run.

All functions take plain arrays (a history row's positions, or a live DEM's): grain
outlines ``(2, k)``, centroid positions and velocities ``(2, N)``. Lengths in metres;
normalise with the packing's ``L0``, ``H0`` and ``tau_c = sqrt(H0 / g)``.

- :func:`front_position`: the run-out ``L(t)``: the right end of the grains connected
  to the left wall (gaps wider than ``gap`` cut off grains thrown ahead);
- :func:`deposit_profile`, :func:`height_at`: the free surface ``h(x)`` (the upper
  boundary of the grains);
- :func:`kinetic_energies`: horizontal, vertical and rotational kinetic energy;
- :func:`front_froude`: ``Fr = (dL/dt) / sqrt(g H0)``;
- :func:`flowing_solid_fraction`: grain area over hull area of the moving grains.
"""

from __future__ import annotations

import numpy as np

from ..dem import Polygon
from ..dem.polygon import polygon_area, polygon_properties
from ..packing import Packing

__all__ = ["deposit_profile", "flowing_solid_fraction", "front_froude", "front_position",
           "grain_outlines", "height_at", "kinetic_energies", "local_outlines", "masses",
           "normalised_runout", "realisations"]


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
    lo = np.array([P[0].min() for P in outlines])
    hi = np.array([P[0].max() for P in outlines])
    if gap is None:
        gap = float((hi - lo).max())
    order = np.argsort(lo)
    end = x_wall
    for k in order:
        if lo[k] > end + gap:
            break
        end = max(end, hi[k])
    return float(end)


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
