"""Checks of a DEM system's starting state: inside its box, no overlaps beyond a tolerance."""

from __future__ import annotations

import numpy as np

from . import pipeline
from .broadphase import NeighbourList
from .particles import rotate_outlines


def check_domain(system) -> None:
    """Every particle inside the box ``system.domain`` (if given), else one line naming it."""
    if system.domain is None or system.n == 0:
        return
    x0, y0, x1, y1 = system.domain
    tol = 1e-9 * max(x1 - x0, y1 - y0)
    V = rotate_outlines(system.particles.shadow_local, system.particles.q)
    lo, hi = V.min(axis=1), V.max(axis=1)
    bad = (lo[:, 0] < x0 - tol) | (lo[:, 1] < y0 - tol) | (hi[:, 0] > x1 + tol) | (
        hi[:, 1] > y1 + tol)
    if np.any(bad):
        k = int(np.nonzero(bad)[0][0])
        raise ValueError(
            f"particles[{k}].shape spans x in [{lo[k, 0]:.6g}, {hi[k, 0]:.6g}], "
            f"y in [{lo[k, 1]:.6g}, {hi[k, 1]:.6g}]: must lie inside the box "
            f"domain = {system.domain}")


def check_overlaps(system, tol: float) -> None:
    """No two particles (or a particle and a wall) overlapping by more than ``tol`` of the
    smaller area at the start, else one line naming them."""
    if system.n == 0:
        return
    q = system.particles.q
    I, J = NeighbourList(0.0).update(q[:2], system.particles.radius, system.walls.vertices)
    V = pipeline.body_vertices(system, q)
    I, J, area, *_ = pipeline.contact_geometry(system, V, q, I, J)
    ref = np.where(J < system.n, np.minimum(system.particles.area[I],
                                          system.particles.area[np.minimum(J, system.n - 1)]),
                   system.particles.area[I])
    rel = area / ref
    if np.any(rel > tol):
        k = int(np.argmax(rel))
        other = (f"particles[{J[k]}]" if J[k] < system.n
                 else f"walls[{J[k] - system.n}]")
        raise ValueError(
            f"particles[{I[k]}] and {other} overlap at start by {rel[k]:.3g} of the "
            f"smaller area: must be <= overlap_tolerance = {tol:g}")
