"""A particle reaching a wall or another particle with nothing to stop its core.

The fluid mesh lies between the particle *cores*; in 2D a smooth particle never
touches a wall in finite time, but the discrete lubrication layer of a mesh with
one element across a closing gap is too weak to stop it, so without contacts (or
with contacts between shadows that coincide with the cores) a core keeps
approaching until no mesh can follow. Measured (24-gon of radius 0.5 mm,
2650 kg/m^3, in water, released 0.2 mm above the floor of a 3 mm box, steps of
2 ms, no contacts): still 1.7 cm/s at a gap of 0.02 outline edges; below
:data:`LANDING_GAP` the steps that keep the mesh valid shrank from 0.5 ms to
1e-6 s within five steps, every one remeshed, until a triangle inverted at any
step ("mesh motion: triangle ... is inverted", after 4 step halvings down to
1.2e-7 s).

:func:`core_gaps` measures each core's smallest distance to the walls and to the
other cores; the coupled stepper remeshes once when a gap falls below
:data:`LANDING_GAP` outline edges and stops with :func:`landing_message` (one
line, with the fix) if it is still below at the next step.
"""

from __future__ import annotations

import numpy as np

#: Smallest gap between a core and a wall or another core that the mesh follows, in
#: outline edges of the particle.
LANDING_GAP = 0.05


def _point_edges(points: np.ndarray, outline: np.ndarray) -> float:
    """Smallest distance from ``points`` ``(2, M)`` to the edges of ``outline`` ``(2, n)``."""
    A = outline[:, :, None]
    E = np.roll(outline, -1, axis=1)[:, :, None] - A
    R = points[:, None, :] - A
    t = np.clip(np.sum(R * E, axis=0) / np.sum(E * E, axis=0), 0.0, 1.0)
    return float(np.hypot(*(R - t * E)).min())


def core_gaps(cores, domain, cutoff=None) -> tuple[np.ndarray, np.ndarray]:
    """Each core's smallest distance to the domain's walls and to the other cores.

    Parameters
    ----------
    cores : list of (2, n) ndarray
        Core outlines (counter-clockwise, disjoint, inside the domain).
    domain : tuple or (2, m) ndarray
        ``(x0, y0, x1, y1)`` or a convex counter-clockwise outline.
    cutoff : float or (K,) ndarray, optional
        Gaps that matter only below this (per core): pairs of cores whose bounding
        circles are farther apart than both cores' cutoffs are not measured. Default:
        every gap exact.

    Returns
    -------
    gaps : (K,) ndarray
        Smallest distance of core ``k`` to a wall or another core; with ``cutoff``,
        exact where it is below the cutoff, else only known to be at or above it.
    partner : (K,) ndarray of int
        What is that close: ``j >= 0`` core ``j``, ``-1 - e`` the domain edge ``e``.

    Notes
    -----
    A convex core's closest point to a wall is a vertex, so the walls take one
    distance query over all vertices. Candidate pairs come from a k-d tree on the
    centres (bounding circles), so the cost grows with the number of close pairs,
    not with its square (25 cores in a dense column: 300 pairs measured at every
    step before, none with the cutoff of the landing check).
    """
    from scipy.spatial import cKDTree

    import meshing.geometry as mg

    D, _ = mg.as_domain(domain)
    K = len(cores)
    counts = np.array([P.shape[1] for P in cores])
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    d, e = mg.edge_distance(D, np.hstack(cores))
    first = np.minimum.reduceat(d, start)
    at = np.array([s + int(np.argmin(d[s:s + m])) for s, m in zip(start, counts,
                                                                   strict=True)])
    gaps, partner = first.astype(float), (-1 - e[at]).astype(np.int64)
    if K < 2:
        return gaps, partner
    c = np.array([P.mean(axis=1) for P in cores])
    r = np.array([np.hypot(*(P - P.mean(axis=1, keepdims=True))).max() for P in cores])
    bound = gaps.copy() if cutoff is None else np.minimum(gaps, np.broadcast_to(cutoff, K))
    pairs = cKDTree(c).query_pairs(2.0 * r.max() + bound.max(), output_type="ndarray")
    for a, b in pairs:
        # bounding circles closer than the gap either may still have
        if np.hypot(*(c[a] - c[b])) - r[a] - r[b] >= max(bound[a], bound[b]):
            continue
        dab = min(_point_edges(cores[a], cores[b]), _point_edges(cores[b], cores[a]))
        for i, j in ((a, b), (b, a)):
            if dab < gaps[i]:
                gaps[i], partner[i] = dab, j
    return gaps, partner


def landed(gaps: np.ndarray, edge: np.ndarray) -> int | None:
    """The particle with the smallest gap below :data:`LANDING_GAP` edges, or None."""
    ratio = np.asarray(gaps) / np.asarray(edge)
    k = int(np.argmin(ratio))
    return k if ratio[k] < LANDING_GAP else None


def landing_message(k: int, gap: float, partner: int, edge: float, wall_names,
                    contacts: bool, cores_are_shadows: bool, t: float) -> str:
    """One line: which particle reached what, how close, and the fix."""
    if partner >= 0:
        what = f"particle {partner}"
    else:
        name = wall_names[-1 - partner]
        what = f"the {name} wall" if name else f"the wall (domain edge {-1 - partner})"
    if not contacts:
        fix = ("enable contacts ([effects] contacts = true) and give the particles a "
               "core_ratio below 1 (e.g. 0.95), so that their shadows touch while the "
               "fluid keeps a gap between the cores")
    elif cores_are_shadows:
        fix = ("give the particles a core_ratio below 1 (e.g. 0.95): with contacts between "
               "shadows equal to the cores the fluid gap closes before they touch")
    else:
        fix = ("raise contacts.E or lower core_ratio: the contacts let the shadows overlap "
               "by more than the gap between shadow and core")
    return (f"run stopped at t={t:.6g} s: particle {k} reached {what}: the gap between "
            f"their fluid boundaries is {gap:.3g} m, below {LANDING_GAP:g} outline edges "
            f"({LANDING_GAP * edge:.3g} m), the smallest the mesh follows, after a remesh; "
            f"{fix}")


def landing_check(dem, domain, edge, contacts: bool, t: float) -> str | None:
    """The :func:`landing_message` of the particle whose core is closest (relative to its
    outline edge ``edge`` ``(K,)``) to a wall or another core, if that is below
    :data:`LANDING_GAP` edges; else None."""
    import meshing.geometry as mg

    edge = np.asarray(edge, dtype=float)
    gaps, partner = core_gaps(dem.core_outlines(), domain, cutoff=LANDING_GAP * edge)
    k = landed(gaps, edge)
    if k is None:
        return None
    p = dem.particles
    same = bool(np.array_equal(p.core_local, p.shadow_local))
    return landing_message(k, float(gaps[k]), int(partner[k]), float(edge[k]),
                           mg.as_domain(domain)[1], contacts, same, t)
