"""The per-step stages of the DEM, each a small function testable alone.

Order within one force evaluation (Yade-style explicit pipeline):

1. :func:`reset_forces` - gravity (buoyancy-reduced), external forces/torques;
2. :func:`broad_phase` - candidate pairs from bounding circles;
3. :func:`contact_geometry` - overlap area, centroid, normal of overlapping pairs;
4. :func:`apply_contact_law` - contact forces, tangential history;
5. :func:`accumulate` - sum contact forces and torques onto the particles.

The integrator (:mod:`.integrator`) calls this sequence once per step at the
predicted state.
"""

from __future__ import annotations

import numpy as np

from . import overlap_numba
from .contact_law import ContactForces, contact_forces, contact_length, rolling_torque
from .overlap import contact_normals, overlap_geometry
from .particles import rotate_outlines

__all__ = ["accumulate", "apply_contact_law", "body_vertices", "broad_phase",
           "contact_geometry", "reset_forces"]


def reset_forces(system, t: float):
    """Body forces ``(2, N)`` and torques ``(N,)`` before contacts.

    Gravity acts with the buoyancy-reduced weight ``(rho_p A - rho_f A_core) g``: the
    fluid's buoyancy on the core, the outline the fluid sees, as in coupled runs;
    ``system.external_force``/``external_torque`` are added, and so is every
    callable in ``system.force_callbacks`` (``f(system, t) -> (F, T)``).
    """
    p = system.particles
    F = np.outer(system.gravity, p.density * p.area - system.fluid_density * p.core_area)
    F += system.external_force
    T = system.external_torque.copy()
    for f in system.force_callbacks:
        Fc, Tc = f(system, t)
        F += Fc
        T += Tc
    return F, T


def body_vertices(system, q: np.ndarray) -> np.ndarray:
    """``(N + W, nmax, 2)`` world shadow vertices of particles then walls."""
    Vp = rotate_outlines(system._shadow_local, q)
    return np.concatenate([Vp, system._wall_vertices], axis=0)


def broad_phase(system, q: np.ndarray):
    """Candidate pairs ``(I, J)`` (walls as ``J >= N``) from the Verlet list."""
    return system.neighbours.update(q[:2], system.particles.radius,
                                    system.walls.vertices)


def contact_geometry(system, V: np.ndarray, q: np.ndarray, I: np.ndarray, J: np.ndarray):
    """Overlap geometry of the candidate pairs; keeps overlapping pairs only.

    Returns
    -------
    I, J
        Indices of the overlapping pairs.
    area, point, normal, length
        Overlap area, centroid (point of action), unit normal ``i -> j`` and
        chord length, for those pairs.
    """
    N = system.n
    part = J < N
    Xb = system.body_centroids(q)
    R = system.particles.radius
    d = Xb[:, I] - Xb[:, J]
    Rj = np.where(part, R[np.where(part, J, 0)], np.inf)
    near = ~part | ((d * d).sum(axis=0) < (R[I] + Rj) ** 2)
    I, J = I[near], J[near]
    if system.backend == "numba":
        g = overlap_numba.overlap_pairs_numba(V, system._count, I, J)
    else:
        g = overlap_geometry(V[I], V[J])
    keep = g.area > 0.0
    I, J = I[keep], J[keep]
    Xi = q[:2, I]
    Xj = Xb[:, J]
    g.area, g.centroid, g.chord = g.area[keep], g.centroid[:, keep], g.chord[:, keep]
    g.length, g.ncross = g.length[keep], g.ncross[keep]
    normal = contact_normals(g, Xi, Xj)
    return I, J, g.area, g.centroid, normal, g.length


def apply_contact_law(system, I, J, area, point, normal, length, q, v, dt: float):
    """:class:`ContactForces` for the overlapping pairs, using the stored history."""
    N = system.n
    wall = J >= N
    Jp = np.where(wall, 0, J)
    Xb = system.body_centroids(q)
    Vi, wi = v[:2, I], v[2, I]
    Vj = np.where(wall, 0.0, v[:2, Jp])
    wj = np.where(wall, 0.0, v[2, Jp])
    mi = system.mass[I]
    mj = system.mass[Jp]
    m_eff = np.where(wall, mi, mi * mj / (mi + mj))
    keys = I * (N + system.walls.n) + J
    ft_old = system.contact_history.lookup(keys)
    fn, ft, ft_spring, energy = contact_forces(
        system.law, area, point, normal, length, q[:2, I], Xb[:, J], Vi, Vj, wi, wj,
        m_eff, wall, ft_old, dt)
    cf = ContactForces(I, J, point, normal, fn, ft, ft_spring, energy, area)
    cf.keys = keys
    if system.law.rolls:
        _resist_rolling(system, cf, q, Xb, wi - wj, wall, length, dt)
    return cf


def _resist_rolling(system, cf: ContactForces, q, Xb, w_rel, wall, length, dt: float) -> None:
    """Set ``cf.mr``, ``cf.mr_spring`` (:func:`~.contact_law.rolling_torque`) and add
    the rolling springs' energy to ``cf.energy``."""
    I, J = cf.i, cf.j
    Jp = np.where(wall, 0, J)
    r0 = np.hypot(*(cf.point - q[:2, I]))
    r1 = np.hypot(*(cf.point - Xb[:, J]))
    with np.errstate(divide="ignore", invalid="ignore"):
        R_r = np.where(wall, r0, r0 * r1 / (r0 + r1))
        Ii = system.inertia[I] + system.mass[I] * r0**2
        Ij = system.inertia[Jp] + system.mass[Jp] * r1**2
        I_r = np.where(wall, Ii, Ii * Ij / (Ii + Ij))
    kn = system.law.E * length / contact_length(r0, r1, wall)
    mr_old = system.contact_history.lookup(cf.keys, system.contact_history.mr)
    cf.mr, cf.mr_spring, energy = rolling_torque(system.law, cf.fn, kn, R_r, w_rel, I_r,
                                                 mr_old, dt)
    cf.energy = cf.energy + energy


def accumulate(system, cf: ContactForces, q: np.ndarray, F: np.ndarray, T: np.ndarray):
    """Add contact forces and torques (about the centroids) to ``F``, ``T`` in place."""
    N = system.n
    if cf.i.size == 0:
        return F, T
    f = cf.force_on_i
    part = cf.j < N
    # body i gets f, particle j gets -f; walls (j >= N) take nothing
    idx = np.concatenate([cf.i, cf.j[part]])
    fx = np.concatenate([f[0], -f[0, part]])
    fy = np.concatenate([f[1], -f[1, part]])
    r = cf.point[:, np.concatenate([np.arange(cf.i.size), np.nonzero(part)[0]])] - q[:2, idx]
    F[0] += np.bincount(idx, weights=fx, minlength=N)
    F[1] += np.bincount(idx, weights=fy, minlength=N)
    T += np.bincount(idx, weights=r[0] * fy - r[1] * fx, minlength=N)
    if cf.mr is not None:
        T += np.bincount(idx, weights=np.concatenate([cf.mr, -cf.mr[part]]), minlength=N)
    return F, T
