"""Pore flux through a touching honeycomb of hexagons: the mesh-accuracy case of gap flows.

A touching 3 x 3 honeycomb of hexagons (shadow circumradius 0.5 mm, cores ``CORE`` of
it, shadows touching each other and the floor) in the 20 x 10 mm box, a slow parabolic
inflow on the left (peak 1 mm/s), no slip on the floor, the top and the cores,
do-nothing outflow on the right; steady Stokes. The pore flux is the integral of
``u_x`` over the pores on the vertical line through the middle column's centres: the
fluid intervals from the floor to the column's top core (Gauss-Legendre on each).
"""

from __future__ import annotations

import time

import numpy as np

BOX = (0.0, 0.0, 20e-3, 10e-3)
R = 0.5e-3           # shadow circumradius
CORE = 0.8           # core ratio
X0 = 5e-3            # first column's centre
U_MAX = 1e-3         # peak inflow (m/s)
GAUSS = 40           # Gauss points per fluid interval


def hexagon(c, r=CORE * R):
    """The regular hexagon of circumradius ``r`` about ``c``: ``(2, 6)``."""
    th = 2.0 * np.pi * np.arange(6) / 6
    return np.vstack([c[0] + r * np.cos(th), c[1] + r * np.sin(th)])


def honeycomb(nx=3, ny=3, x0=X0, core=CORE):
    """Cores (``core`` of the shadow) of hexagons whose shadows tile the floor and each
    other (all touching)."""
    a = R * np.sqrt(3.0) / 2.0
    return [hexagon((x0 + i * 1.5 * R, a + 2 * a * j + (a if i % 2 else 0.0)), core * R)
            for i in range(nx) for j in range(ny)]


def fluid_intervals(x, top, cores):
    """The parts of the segment ``(x, 0) -> (x, top)`` outside every core."""
    cuts = []
    for P in cores:
        if P[0].min() < x < P[0].max():
            # crossing of the vertical line with the convex polygon's edges
            Q = np.roll(P, -1, axis=1)
            s = (x - P[0]) / np.where(Q[0] != P[0], Q[0] - P[0], np.inf)
            ok = (s >= 0.0) & (s <= 1.0)
            y = P[1, ok] + s[ok] * (Q[1, ok] - P[1, ok])
            cuts.append((y.min(), y.max()))
    cuts.sort()
    out, y0 = [], 0.0
    for a, b in cuts:
        if a > y0:
            out.append((y0, min(a, top)))
        y0 = max(y0, b)
    if y0 < top:
        out.append((y0, top))
    return out


def line_fluxes(value, cores, x: float | None = None, top: float | None = None):
    """Steady Stokes fluxes (m^2/s per unit depth) through each fluid interval of a
    vertical line, and the solve's wall time.

    The line is by default the middle column's, from the floor to the top of the block's
    shadows: its last interval, above the column's top core, is open to the flow over the
    block, the others are the pores. ``x``, ``top``: another line ``(x, 0) -> (x, top)``.
    """
    from skfem_granular.fluid import Fluid, solve_steady

    H = BOX[3] - BOX[1]
    vel = {"left": lambda x, y: (U_MAX * 4.0 * y * (H - y) / H ** 2, 0.0 * y),
           "top": (0.0, 0.0), "bottom": (0.0, 0.0),
           **{f"particle{k}": (0.0, 0.0) for k in range(len(cores))}}
    t0 = time.perf_counter()
    flow = solve_steady(value.mesh, Fluid(density=1000.0, viscosity=1e-3), vel)
    a = R * np.sqrt(3.0) / 2.0
    x = X0 + 1.5 * R if x is None else x
    top = 2 * a * 3 + a if top is None else top
    g, w = np.polynomial.legendre.leggauss(GAUSS)
    q = []
    for y0, y1 in fluid_intervals(x, top, cores):
        y = 0.5 * (y0 + y1) + 0.5 * (y1 - y0) * g
        u = flow.velocity(np.vstack([np.full_like(y, x), y]))[0]
        q.append(0.5 * (y1 - y0) * float(w @ u))
    return q, time.perf_counter() - t0
