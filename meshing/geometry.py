"""Input outlines: validation and small convex-polygon helpers.

All outlines are ``(2, N)`` arrays of counter-clockwise vertices of a convex
polygon. Every check raises :class:`ValueError` with the parameter name and
the allowed range, so that bad input never surfaces as a traceback from inside
numpy or ``triangle``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

RECT_EDGES = ("bottom", "right", "top", "left")


def as_outline(obj: object, name: str) -> NDArray[np.float64]:
    """Return a validated convex counter-clockwise outline.

    Parameters
    ----------
    obj
        A ``(2, N)`` array-like of vertices, or an object with a
        ``.vertices`` attribute of that form.
    name
        Parameter name used in error messages, e.g. ``"particles[2]"``.

    Returns
    -------
    ndarray
        ``(2, N)`` float array, ``N >= 3``.

    Raises
    ------
    ValueError
        If the outline is malformed, clockwise, self-intersecting or not
        convex.
    """
    verts = getattr(obj, "vertices", obj)
    try:
        V = np.array(verts, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{name}: expected a (2, N) array of vertices ({err})") from None
    if V.ndim != 2 or V.shape[0] != 2 or V.shape[1] < 3:
        raise ValueError(f"{name}: expected a (2, N) array of vertices with N >= 3, "
                         f"got shape {V.shape}")
    if not np.all(np.isfinite(V)):
        raise ValueError(f"{name}: vertices must be finite numbers")
    E = np.roll(V, -1, axis=1) - V
    L = np.hypot(*E)
    scale = float(np.max(L))
    if scale <= 0.0:
        raise ValueError(f"{name}: all vertices coincide")
    short = np.flatnonzero(L <= 1e-12 * scale)
    if short.size:
        raise ValueError(f"{name}: vertices {short[0]} and {(short[0] + 1) % V.shape[1]} "
                         "coincide; repeated vertices are not allowed")
    area = 0.5 * float(np.sum(V[0] * np.roll(V[1], -1) - np.roll(V[0], -1) * V[1]))
    if area < 0.0:
        raise ValueError(f"{name}: outline is clockwise (signed area {area:.3g}); "
                         "vertices must be counter-clockwise")
    Eprev = np.roll(E, 1, axis=1)
    cross = Eprev[0] * E[1] - Eprev[1] * E[0]
    tol = 1e-9 * np.roll(L, 1) * L
    bad = np.flatnonzero(cross < -tol)
    if bad.size:
        raise ValueError(f"{name}: outline is not convex (vertex {bad[0]} turns clockwise)")
    turn = np.arctan2(cross, np.sum(Eprev * E, axis=0))
    winding = float(np.sum(turn)) / (2.0 * np.pi)
    if abs(winding - 1.0) > 1e-6:
        raise ValueError(f"{name}: outline is self-intersecting (winds {winding:.0f} times "
                         "around its interior); a convex outline winds once")
    return V


def as_domain(domain: object) -> tuple[NDArray[np.float64], tuple[str, ...]]:
    """Return the domain outline and one boundary name per edge.

    Parameters
    ----------
    domain
        ``(x0, y0, x1, y1)`` rectangle with ``x0 < x1``, ``y0 < y1``, or a
        convex counter-clockwise ``(2, N)`` outline.

    Returns
    -------
    vertices : ndarray
        ``(2, N)`` corners, counter-clockwise. A rectangle starts at
        ``(x0, y0)``.
    edge_names : tuple of str
        ``"bottom", "right", "top", "left"`` for a rectangle, else ``""``
        for every edge (all edges belong to ``"wall"``).
    """
    arr = np.asarray(getattr(domain, "vertices", domain), dtype=object)
    if arr.ndim == 1 and arr.shape[0] == 4:
        try:
            x0, y0, x1, y1 = (float(v) for v in arr)
        except (TypeError, ValueError):
            raise ValueError("domain: expected (x0, y0, x1, y1) numbers or a (2, N) "
                             "outline") from None
        if not all(np.isfinite([x0, y0, x1, y1])):
            raise ValueError("domain: (x0, y0, x1, y1) must be finite")
        if not (x0 < x1 and y0 < y1):
            raise ValueError(f"domain: need x0 < x1 and y0 < y1, got ({x0:g}, {y0:g}, "
                             f"{x1:g}, {y1:g})")
        V = np.array([[x0, x1, x1, x0], [y0, y0, y1, y1]])
        return V, RECT_EDGES
    V = as_outline(domain, "domain")
    return V, ("",) * V.shape[1]


def outline_lengths(V: NDArray[np.float64]) -> NDArray[np.float64]:
    """Edge lengths of a closed outline, edge ``k`` from vertex ``k`` to ``k+1``."""
    return np.hypot(*(np.roll(V, -1, axis=1) - V))


def subdivide(V: NDArray[np.float64], delta_l: float | None) -> NDArray[np.float64]:
    """Split outline edges so that no segment exceeds ``delta_l``.

    The new nodes lie on the straight edges, equally spaced; the original
    vertices are kept, first, in order. ``delta_l=None`` returns ``V``.
    """
    if delta_l is None:
        return V
    L = outline_lengths(V)
    if L.sum() / delta_l > MAX_OUTLINE_NODES:
        raise ValueError(f"delta_l = {delta_l:.3g}: would put {L.sum() / delta_l:.2g} nodes on "
                         f"one outline; must be >= {L.sum() / MAX_OUTLINE_NODES:.3g} (at most "
                         f"{MAX_OUTLINE_NODES:.0e} nodes per outline)")
    n = np.maximum(1, np.ceil(L / delta_l * (1.0 - 1e-12))).astype(int)
    W = np.roll(V, -1, axis=1)
    parts = [V[:, k:k + 1] + (W[:, k:k + 1] - V[:, k:k + 1]) * (np.arange(n[k]) / n[k])
             for k in range(V.shape[1])]
    return np.hstack(parts)


def width(V: NDArray[np.float64]) -> float:
    """Smallest width of a convex outline: the least distance between an edge's line
    and the vertex farthest from it (a rectangle's shorter side)."""
    E = np.roll(V, -1, axis=1) - V
    n = np.vstack([-E[1], E[0]]) / np.hypot(*E)           # inward normals (ccw)
    d = np.einsum("in,inm->nm", n, V[:, None, :] - V[:, :, None])   # (edge, vertex)
    return float(np.min(np.max(d, axis=1)))


def centroid(V: NDArray[np.float64]) -> NDArray[np.float64]:
    """Area centroid of a polygon, shape ``(2,)``."""
    x, y = V
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    c = x * yn - xn * y
    A = 0.5 * np.sum(c)
    return np.array([np.sum((x + xn) * c), np.sum((y + yn) * c)]) / (6.0 * A)


def centroids(outlines: Sequence[NDArray[np.float64]]) -> NDArray[np.float64]:
    """Area centroids of many polygons at once, ``(K, 2)`` (:func:`centroid` of each)."""
    if not len(outlines):
        return np.zeros((0, 2))
    counts = np.array([P.shape[1] for P in outlines])
    X = np.hstack(outlines)
    start = np.cumsum(counts) - counts
    nxt = np.arange(X.shape[1]) + 1
    nxt[start + counts - 1] = start
    x, y = X
    xn, yn = x[nxt], y[nxt]
    c = x * yn - xn * y
    A = 0.5 * np.add.reduceat(c, start)
    return np.column_stack([np.add.reduceat((x + xn) * c, start),
                            np.add.reduceat((y + yn) * c, start)]) / (6.0 * A[:, None])


def edge_distance(V: NDArray[np.float64], x: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """Signed distance of points to a convex outline's edge lines.

    Returns ``(d, k)``: for each point the distance to the closest edge
    segment (``(M,)``) and that edge's index. Positive inside.
    """
    A = V[:, :, None]
    E = np.roll(V, -1, axis=1)[:, :, None] - A            # (2, n, 1)
    L2 = np.sum(E * E, axis=0)                              # (n, 1)
    R = x[:, None, :] - A                                   # (2, n, M)
    t = np.clip(np.sum(R * E, axis=0) / L2, 0.0, 1.0)       # (n, M)
    D = np.hypot(*(R - t * E))                              # (n, M)
    k = np.argmin(D, axis=0)
    d = D[k, np.arange(x.shape[1])]
    return np.where(inside(V, x), d, -d), k


def inside(V: NDArray[np.float64], x: NDArray[np.float64], margin: float = 0.0) -> NDArray:
    """Boolean ``(M,)``: points strictly inside a convex ccw outline by ``margin``."""
    A = V[:, :, None]
    E = np.roll(V, -1, axis=1)[:, :, None] - A
    L = np.hypot(*E)
    R = x[:, None, :] - A
    cross = (E[0] * R[1] - E[1] * R[0]) / L
    return np.all(cross > margin, axis=0)


def project_to_edge(V: NDArray[np.float64], k: NDArray, x: NDArray[np.float64]) -> NDArray:
    """Parameter (arc length from vertex ``k``) of the projection of ``x`` on edge ``k``."""
    A = V[:, k]
    E = np.roll(V, -1, axis=1)[:, k] - A
    L = np.hypot(*E)
    return np.clip(np.sum((x - A) * E, axis=0) / L, 0.0, L)


def polygons_overlap(P: NDArray[np.float64], Q: NDArray[np.float64]) -> bool:
    """True when two convex polygons intersect (separating axis test)."""
    for S, T in ((P, Q), (Q, P)):
        E = np.roll(S, -1, axis=1) - S
        n = np.vstack([E[1], -E[0]])                        # outward normals (ccw)
        s_max = np.sum(n * S, axis=0)
        t_min = np.min(n.T @ T, axis=1)
        if np.any(t_min >= s_max):
            return False
    return True


#: Most nodes one particle outline may get from ``delta_l``.
MAX_OUTLINE_NODES = 100_000
#: Most triangles a uniform mesh may have (about 2 GB of P2/P1 system at this size).
MAX_ELEMENTS = 5_000_000
#: Smallest particle extent relative to the domain that meshing accepts.
MIN_RELATIVE_SIZE = 1e-5


def check_layout(D: NDArray[np.float64], particles: Sequence[NDArray[np.float64]]) -> None:
    """Raise ValueError if a particle leaves the domain or two particles overlap."""
    size = float(np.max(np.ptp(D, axis=1)))
    if not len(particles):
        return
    counts = np.array([P.shape[1] for P in particles])
    start = np.cumsum(counts) - counts
    X = np.hstack(particles)
    out = ~inside(D, X)
    extent = np.maximum(*(np.maximum.reduceat(X, start, axis=1)
                          - np.minimum.reduceat(X, start, axis=1)))
    bad = np.logical_or.reduceat(out, start) | (extent < MIN_RELATIVE_SIZE * size)
    if np.any(bad):     # the first particle in error, as a loop over them would find it
        i = int(np.argmax(bad))
        P = particles[i]
        out = np.flatnonzero(out[start[i]:start[i] + counts[i]])
        if out.size:
            raise ValueError(f"particles[{i}]: vertex {out[0]} at ({P[0, out[0]]:g}, "
                             f"{P[1, out[0]]:g}) is not strictly inside the domain")
        raise ValueError(f"particles[{i}]: extent {extent[i]:.3g} is below "
                         f"{MIN_RELATIVE_SIZE:g} x the domain size {size:.3g}; such a "
                         "particle cannot be meshed (round-off); must be larger")
    if len(particles) < 2:
        return
    from scipy.spatial import cKDTree  # here: scipy.spatial takes ~0.1 s to import

    C = centroids(particles)
    R = np.maximum.reduceat(np.hypot(*(X - np.repeat(C.T, counts, axis=1))), start)
    for i, j in sorted(cKDTree(C).query_pairs(2.0 * float(R.max()))):
        if np.hypot(*(C[i] - C[j])) < R[i] + R[j] and polygons_overlap(particles[i],
                                                                      particles[j]):
            raise ValueError(f"particles[{i}] and particles[{j}] overlap; particles "
                             "must be disjoint")


def as_particles(particles: object) -> list[NDArray[np.float64]]:
    """Validate a sequence of particle outlines."""
    if particles is None:
        return []
    if isinstance(particles, np.ndarray) and particles.ndim == 2:
        raise ValueError("particles: expected a list of (2, N) outlines, got one array; "
                         "wrap it in a list")
    try:
        items = list(particles)  # type: ignore[call-overload]
    except TypeError:
        raise ValueError("particles: expected a list of (2, N) outlines") from None
    return [as_outline(P, f"particles[{i}]") for i, P in enumerate(items)]


def positive(value: ArrayLike | None, name: str, upper: float | None = None,
             what: str = "") -> float | None:
    """Validate an optional positive scalar (``0 < value [<= upper]``)."""
    if value is None:
        return None
    try:
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a number, got {value!r}") from None
    if not np.isfinite(v) or v <= 0.0:
        raise ValueError(f"{name}: must be > 0, got {v!r}")
    if upper is not None and v > upper:
        raise ValueError(f"{name}: must be <= {upper:.6g}{what}, got {v:.6g}")
    return v


def clip_convex(P: NDArray[np.float64], D: NDArray[np.float64]) -> NDArray[np.float64]:
    """Part of convex polygon ``P`` inside convex polygon ``D`` (both ccw).

    Sutherland-Hodgman clipping; returns a ``(2, M)`` ccw outline, ``M = 0``
    when they do not intersect.
    """
    out = P.T.copy()
    for k in range(D.shape[1]):
        a, b = D[:, k], D[:, (k + 1) % D.shape[1]]
        e = b - a
        if out.shape[0] == 0:
            break
        side = e[0] * (out[:, 1] - a[1]) - e[1] * (out[:, 0] - a[0])
        res = []
        for i in range(out.shape[0]):
            j = (i + 1) % out.shape[0]
            if side[i] >= 0.0:
                res.append(out[i])
            if (side[i] >= 0.0) != (side[j] >= 0.0):
                t = side[i] / (side[i] - side[j])
                res.append(out[i] + t * (out[j] - out[i]))
        out = np.array(res).reshape(-1, 2)
        if out.shape[0]:
            # drop repeated points (vertices exactly on a clipping line)
            step = np.hypot(*(np.roll(out, -1, axis=0) - out).T)
            out = out[step > 1e-12 * max(float(np.max(np.abs(out))), 1e-300)]
    return out.T
