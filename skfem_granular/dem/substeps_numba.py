"""Compiled loop over the DEM's substeps (numba): the whole predictor-corrector step.

:meth:`DEMSystem.advance <skfem_granular.dem.DEMSystem.advance>` runs many short
substeps (a coupled step of 0.2 ms takes ~50 through contacts). Per substep the
numpy pipeline of :mod:`.pipeline` makes some 150 small array operations, ~0.2 ms
of interpreter overhead whatever the number of grains; this module runs the same
arithmetic, substep after substep, in one compiled call:

1. the BDF2 predictor (:func:`.integrator.predict`),
2. the Verlet check (the candidate pairs are kept; the loop stops *before* a substep
   whose predicted positions need a rebuild, which the caller then runs through the
   numpy pipeline, :class:`.broadphase.NeighbourList` doing the rebuild),
3. world outlines, the bounding-circle filter and the overlap of every candidate
   pair (:func:`.overlap_numba.pair_overlap`), the contact normals
   (:func:`.overlap.contact_normals`),
4. the contact law (:func:`.contact_law.contact_forces`, with rolling resistance
   :func:`.contact_law.rolling_torque`) with the springs' history, the sums onto the
   particles (:func:`.pipeline.accumulate`),
5. the BDF2 corrector (:func:`.integrator.correct`).

Each expression keeps the order of operations of the numpy version (sums onto a
particle in the order ``numpy.bincount`` takes), so both give the same numbers up to
the last bits of ``cos``/``sin``; ``tests/test_dem_substeps.py`` compares them.
Only the plain case is compiled: no force callbacks, no prescribed motions, a full
BDF2 history (the caller runs the first substep of a restart through the numpy
pipeline).

The kernel calls :func:`.overlap_numba.pair_overlap`, so that module is compiled
first. numba's disk cache of this module does not notice edits of that function:
after changing it, clear ``__pycache__`` (a fresh install has no stale cache).
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import compile_module, lazy_njit
from . import overlap_numba

__all__ = ["run_substeps"]


@lazy_njit
def _normal(g, rx, ry, ax, ay):
    """Unit normal from body i towards the overlap (:func:`.overlap.contact_normals`):
    perpendicular to the chord, or along ``(rx, ry)`` (centroid to overlap) without one,
    or along ``(ax, ay)`` (centroid to centroid) if that vanishes too."""
    nx = -g[0, 4]
    ny = g[0, 3]
    if nx * rx + ny * ry < 0.0:
        nx = -nx
        ny = -ny
    if g[0, 6] < 2 or g[0, 5] <= 0.0:
        if rx * rx + ry * ry > 0.0:
            ax = rx
            ay = ry
        h = max(math.hypot(ax, ay), 1e-300)
        nx = ax / h
        ny = ay / h
    return nx, ny


@lazy_njit
def _stored(hist_keys, hist_values, key):
    """The spring force (or torque) stored for ``key`` (:meth:`.ContactHistory.lookup`)."""
    if hist_keys.shape[0] and hist_values.shape[0]:
        k = min(np.searchsorted(hist_keys, key), hist_keys.shape[0] - 1)
        if hist_keys[k] == key:
            return hist_values[k]
    return 0.0


@lazy_njit
def _rolling(law, fn, kn, r0, r1, wall, w_rel, inertia, mass, i, j, mr_old, dt):
    """Rolling torque, spring torque and spring energy of the contact of ``i`` and ``j``
    (:func:`.contact_law.rolling_torque`; the radius and the inertia about the point of
    action as :func:`.pipeline.apply_contact_law` forms them)."""
    Ii = inertia[i] + mass[i] * r0**2
    if wall:
        R_r = r0
        I_r = Ii
    else:
        R_r = r0 * r1 / (r0 + r1)
        Ij = inertia[j] + mass[j] * r1**2
        I_r = Ii * Ij / (Ii + Ij)
    mu_r = law[6]
    kr = 2.25 * kn * mu_r**2 * R_r**2
    limit = mu_r * R_r * fn
    spring = mr_old - kr * w_rel * dt
    total = spring - law[7] * 2.0 * math.sqrt(I_r * kr) * w_rel
    if abs(total) > limit:  # total != 0 here: limit >= 0
        mr = math.copysign(limit, total)
        mr_spring = mr
    else:
        mr = total
        mr_spring = spring
    energy = mr_spring**2 / (2.0 * kr) if kr > 0 else 0.0
    return mr, mr_spring, energy


@lazy_njit
def _contact(i, j, N, qp, vp, mass, inertia, wall_centroid, g, law, dt, hist_keys, hist_ft,
             hist_mr, nbodies, c_i, c_j, c_point, c_normal, c_fn, c_ft, c_spring, c_energy,
             c_area, c_keys, c_mr, c_mr_spring, C):
    """Contact law (:func:`.contact_law.contact_forces`) of the overlapping pair
    ``(i, j)`` whose overlap is ``g[0]``, recorded as contact ``C``."""
    wall = j >= N
    area = g[0, 0]
    px = g[0, 1]
    py = g[0, 2]
    length = g[0, 5]
    xi0 = qp[0, i]
    xi1 = qp[1, i]
    if wall:
        xj0 = wall_centroid[0, j - N]
        xj1 = wall_centroid[1, j - N]
    else:
        xj0 = qp[0, j]
        xj1 = qp[1, j]
    nx, ny = _normal(g, px - xi0, py - xi1, xj0 - xi0, xj1 - xi1)
    E = law[0]
    mi = mass[i]
    if wall:
        m_eff = mi
        vj0 = 0.0
        vj1 = 0.0
        wj = 0.0
    else:
        mj = mass[j]
        m_eff = mi * mj / (mi + mj)
        vj0 = vp[0, j]
        vj1 = vp[1, j]
        wj = vp[2, j]
    wi = vp[2, i]
    ri0 = px - xi0
    ri1 = py - xi1
    rj0 = px - xj0
    rj1 = py - xj1
    r0 = math.hypot(ri0, ri1)
    r1 = math.hypot(rj0, rj1)
    if wall:
        L = 4.0 * r0
    else:
        L = 4.0 * r0 * r1 / (r0 + r1)
    L = max(L, 1e-12 * max(r0, 1e-300))
    fel = E * area / L
    ux = vp[0, i] - wi * ri1 - (vj0 - wj * rj1)
    uy = vp[1, i] + wi * ri0 - (vj1 + wj * rj0)
    vn = ux * nx + uy * ny
    vt = -ux * ny + uy * nx
    kn = E * length / L
    fd = law[2] * math.sqrt(m_eff * E) * length * vn / L
    fd = min(max(fd, -fel), law[5] * fel)
    fn = fel + fd
    kt = law[4] * kn
    key = i * nbodies + j
    spring = _stored(hist_keys, hist_ft, key) - kt * vt * dt
    total = spring - law[3] * math.sqrt(m_eff * kt) * vt
    limit = law[1] * fn
    if abs(total) > limit:  # slip (total != 0 here: limit >= 0)
        ft = math.copysign(limit, total)
        ft_spring = ft
    else:
        ft = total
        ft_spring = spring
    energy = E * area**2 / (2.0 * L * length) if length > 0 else 0.0
    energy += ft_spring**2 / (2.0 * kt) if kt > 0 else 0.0
    if law[6] > 0.0:
        mr, mr_spring, e_r = _rolling(law, fn, kn, r0, r1, wall, wi - wj, inertia, mass, i,
                                      j, _stored(hist_keys, hist_mr, key), dt)
        energy += e_r
        c_mr[C] = mr
        c_mr_spring[C] = mr_spring
    c_i[C] = i
    c_j[C] = j
    c_point[0, C] = px
    c_point[1, C] = py
    c_normal[0, C] = nx
    c_normal[1, C] = ny
    c_fn[C] = fn
    c_ft[C] = ft
    c_spring[C] = ft_spring
    c_energy[C] = energy
    c_area[C] = area
    c_keys[C] = key


@lazy_njit
def _predict(q, v, a, a_prev, dt, w, qp, vp):
    """BDF2 predictor (:func:`.integrator.predict`) into ``qp``, ``vp``."""
    for k in range(q.shape[1]):
        for c in range(3):
            qp[c, k] = q[c, k] + dt * v[c, k] + 0.5 * dt * dt * a[c, k]
            vp[c, k] = v[c, k] + dt * ((1.0 + 0.5 * w) * a[c, k] - 0.5 * w * a_prev[c, k])


@lazy_njit
def _moved(qp, reference):
    """Largest squared displacement of a centre since the candidate pairs were built."""
    moved = 0.0
    for k in range(qp.shape[1]):
        d0 = qp[0, k] - reference[0, k]
        d1 = qp[1, k] - reference[1, k]
        moved = max(moved, d0 * d0 + d1 * d1)
    return moved


@lazy_njit
def _rotate(local, qp, V):
    """World vertices of the particles (:func:`.particles.rotate_outlines`) into ``V``."""
    for k in range(qp.shape[1]):
        cs = math.cos(qp[2, k])
        sn = math.sin(qp[2, k])
        for m in range(V.shape[1]):
            V[k, m, 0] = cs * local[k, m, 0] - sn * local[k, m, 1] + qp[0, k]
            V[k, m, 1] = sn * local[k, m, 0] + cs * local[k, m, 1] + qp[1, k]


@lazy_njit
def _add_force(k, sign, c, qp, c_point, c_normal, c_fn, c_ft, Fx, Fy, Tz):
    """Add ``sign`` times contact ``c``'s force on its body i, and its torque, to body ``k``."""
    nx = c_normal[0, c]
    ny = c_normal[1, c]
    fx = -c_fn[c] * nx + c_ft[c] * -ny
    fy = -c_fn[c] * ny + c_ft[c] * nx
    if sign < 0:
        fx = -fx
        fy = -fy
    Fx[k] += fx
    Fy[k] += fy
    Tz[k] += (c_point[0, c] - qp[0, k]) * fy - (c_point[1, c] - qp[1, k]) * fx


@lazy_njit
def _accelerations(C, N, qp, c_i, c_j, c_point, c_normal, c_fn, c_ft, c_mr, rolls, F0, T0,
                   mass, inertia, F, T, a_star):
    """Forces, torques (:func:`.pipeline.accumulate`: the sums onto a particle in
    ``numpy.bincount``'s order, every i, then every j; the rolling torques summed
    apart and added last) and accelerations."""
    Fx = np.zeros(N)
    Fy = np.zeros(N)
    Tz = np.zeros(N)
    Rz = np.zeros(N)
    for c in range(C):
        _add_force(c_i[c], 1, c, qp, c_point, c_normal, c_fn, c_ft, Fx, Fy, Tz)
        if rolls:
            Rz[c_i[c]] += c_mr[c]
    for c in range(C):
        if c_j[c] < N:
            _add_force(c_j[c], -1, c, qp, c_point, c_normal, c_fn, c_ft, Fx, Fy, Tz)
            if rolls:
                Rz[c_j[c]] += -c_mr[c]
    for k in range(N):
        F[0, k] = F0[0, k] + Fx[k]
        F[1, k] = F0[1, k] + Fy[k]
        T[k] = T0[k] + Tz[k]
        if rolls:
            T[k] = T[k] + Rz[k]
        a_star[0, k] = F[0, k] / mass[k]
        a_star[1, k] = F[1, k] / mass[k]
        a_star[2, k] = T[k] / inertia[k]


@lazy_njit
def _correct(q, v, q_prev, v_prev, a, a_prev, a_star, dt, w):
    """BDF2 corrector (:func:`.integrator.correct`, the coefficients of
    :func:`~skfem_granular.timestep.bdf2_coefficients`), history shifted in place."""
    a0 = (1 + 2 * w) / (dt * (1 + w))
    a1 = -(1 + w) / dt
    a2 = w * w / (dt * (1 + w))
    for k in range(q.shape[1]):
        for c in range(3):
            v_new = (a_star[c, k] - a1 * v[c, k] - a2 * v_prev[c, k]) / a0
            q_new = (v_new - a1 * q[c, k] - a2 * q_prev[c, k]) / a0
            q_prev[c, k] = q[c, k]
            v_prev[c, k] = v[c, k]
            a_prev[c, k] = a[c, k]
            a[c, k] = a_star[c, k]
            q[c, k] = q_new
            v[c, k] = v_new


@lazy_njit
def _substeps(n, dt, q, v, q_prev, v_prev, a, a_prev, dt_prev, F0, T0, mass, inertia,
              radius, local, count, V, wall_centroid, I, J, reference, skin2, hist_keys,
              hist_ft, hist_mr, law, c_i, c_j, c_point, c_normal, c_fn, c_ft, c_spring,
              c_energy, c_area, c_keys, c_mr, c_mr_spring, F, T):
    """Up to ``n`` substeps in place; returns (done, contacts of the last, keys, ft, mr)."""
    N = q.shape[1]
    nmax = V.shape[1]
    rolls = law[6] > 0.0
    qp = np.empty((3, N))
    vp = np.empty((3, N))
    a_star = np.empty((3, N))
    g = np.empty((1, 7))
    Sa, Sb, ea, eb, la, lb, NA, NB, acc, pts = overlap_numba.pair_scratch(nmax)
    C = 0
    for step in range(n):
        w = dt / dt_prev
        _predict(q, v, a, a_prev, dt, w, qp, vp)
        if not _moved(qp, reference) < skin2:
            return step, C, hist_keys, hist_ft, hist_mr
        _rotate(local, qp, V)
        C = 0
        for p in range(I.shape[0]):
            i = I[p]
            j = J[p]
            if j < N:
                d0 = qp[0, i] - qp[0, j]
                d1 = qp[1, i] - qp[1, j]
                if not d0 * d0 + d1 * d1 < (radius[i] + radius[j]) ** 2:
                    continue
            overlap_numba.pair_overlap(V[i], count[i], V[j], count[j], g, 0,
                                       Sa, Sb, ea, eb, la, lb, NA, NB, acc, pts)
            if not g[0, 0] > 0.0:
                continue
            _contact(i, j, N, qp, vp, mass, inertia, wall_centroid, g, law, dt, hist_keys,
                     hist_ft, hist_mr, V.shape[0], c_i, c_j, c_point, c_normal, c_fn, c_ft,
                     c_spring, c_energy, c_area, c_keys, c_mr, c_mr_spring, C)
            C += 1
        _accelerations(C, N, qp, c_i, c_j, c_point, c_normal, c_fn, c_ft, c_mr, rolls, F0,
                       T0, mass, inertia, F, T, a_star)
        _correct(q, v, q_prev, v_prev, a, a_prev, a_star, dt, w)
        dt_prev = dt
        order = np.argsort(c_keys[:C], kind="mergesort")
        hist_keys = c_keys[:C][order].copy()
        hist_ft = c_spring[:C][order].copy()
        if rolls:
            hist_mr = c_mr_spring[:C][order].copy()
    return n, C, hist_keys, hist_ft, hist_mr


def run_substeps(n, dt, q, v, hist, F0, T0, mass, inertia, radius, local, count, V,
                 wall_centroid, pairs, reference, margin, history, law):
    """Up to ``n`` substeps of size ``dt``, compiled; stops before a Verlet rebuild.

    Parameters
    ----------
    n, dt
        Number and size of the substeps.
    q, v
        ``(3, N)`` state, advanced in place.
    hist
        :class:`~.integrator.BDF2History`, complete (``q_prev``, ``a_prev``, ``dt_prev``
        set); updated to describe the new state.
    F0, T0
        ``(2, N)``, ``(N,)`` forces and torques besides the contacts (held).
    mass, inertia, radius
        ``(N,)`` per particle (bounding radius).
    local, count
        ``(N, nmax, 2)`` shadow outlines about the centroids and ``(N + W,)`` vertex
        counts of particles then walls.
    V
        ``(N + W, nmax, 2)`` world vertices, the walls' rows filled (the particles'
        are overwritten).
    wall_centroid
        ``(2, W)``.
    pairs, reference, margin
        The :class:`~.broadphase.NeighbourList`'s candidate pairs, reference centres
        and skin.
    history
        :class:`~.contact_law.ContactHistory`, updated.
    law
        :class:`~.contact_law.ContactLaw`.

    Returns
    -------
    done : int
        Substeps done (``< n`` when the next one needs a rebuild of the candidate
        pairs).
    contacts : tuple or None
        ``(i, j, point, normal, fn, ft, ft_spring, energy, area, keys, mr, mr_spring)``
        of the last substep done (``mr``, ``mr_spring`` ``None`` without rolling
        resistance), ``None`` if none was done.
    F, T
        Total force and torque of the last substep's evaluation.
    """
    compile_module(overlap_numba.__name__)
    I, J = pairs
    P = I.shape[0]
    N = q.shape[1]
    c_i, c_j, c_keys = (np.empty(P, dtype=np.int64) for _ in range(3))
    c_point, c_normal = np.empty((2, P)), np.empty((2, P))
    c_fn, c_ft, c_spring, c_energy, c_area, c_mr, c_mr_spring = (np.empty(P) for _ in range(7))
    F, T = np.empty((2, N)), np.empty(N)
    law_values = np.array([law.E, law.mu, law.gamma, law.gt, law.kt_ratio, law.damping_cap,
                           law.mu_r, law.eta_r])
    arrays = [np.array(x, dtype=float, copy=True) for x in (hist.q_prev, hist.v_prev, hist.a,
                                                            hist.a_prev)]
    done, C, keys, ft, mr = _substeps(
        n, dt, q, v, *arrays, float(hist.dt_prev), F0, T0, mass, inertia, radius, local,
        count, V, wall_centroid, I, J, reference, (0.5 * margin) ** 2, history.keys,
        history.ft, history.mr, law_values, c_i, c_j, c_point, c_normal, c_fn, c_ft, c_spring,
        c_energy, c_area, c_keys, c_mr, c_mr_spring, F, T)
    if done == 0:
        return 0, None, F, T
    hist.q_prev, hist.v_prev, hist.a, hist.a_prev = arrays
    hist.dt_prev = dt
    history.keys, history.ft, history.mr = keys, ft, mr
    rolling = (c_mr[:C], c_mr_spring[:C]) if law.rolls else (None, None)
    contacts = (c_i[:C], c_j[:C], c_point[:, :C], c_normal[:, :C], c_fn[:C], c_ft[:C],
                c_spring[:C], c_energy[:C], c_area[:C], c_keys[:C], *rolling)
    return done, contacts, F, T
