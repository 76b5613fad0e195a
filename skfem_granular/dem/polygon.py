"""Convex polygons: validation, area, centroid, second moment, core outlines.

All vertex arrays are ``(2, N)``, counter-clockwise, without repeating the
first vertex at the end.
"""

from __future__ import annotations

import numpy as np

__all__ = ["Polygon", "polygon_area", "polygon_properties", "validate_outline"]

#: relative tolerance of the convexity / degeneracy checks
GEOMETRY_RTOL = 1e-10


def polygon_area(vertices: np.ndarray) -> float:
    """Signed area of a simple polygon ``(2, N)`` (shoelace formula; positive for
    counter-clockwise vertices, 0 for fewer than three)."""
    V = np.asarray(vertices, dtype=float)
    if V.shape[1] < 3:
        return 0.0
    return 0.5 * float(np.sum(V[0] * np.roll(V[1], -1) - np.roll(V[0], -1) * V[1]))


def polygon_properties(vertices: np.ndarray) -> tuple[float, np.ndarray, float]:
    """Area, centroid and polar second moment of area of a simple polygon.

    Parameters
    ----------
    vertices
        ``(2, N)`` counter-clockwise vertices.

    Returns
    -------
    area
        Signed area (positive for counter-clockwise vertices).
    centroid
        ``(2,)`` centroid.
    J
        Polar second moment of area about the centroid,
        ``int (x - cx)^2 + (y - cy)^2 dA``.
    """
    x0 = vertices.mean(axis=1)
    x, y = vertices[0] - x0[0], vertices[1] - x0[1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    c = x * yn - xn * y
    area = 0.5 * c.sum()
    cx = ((x + xn) * c).sum() / (6.0 * area)
    cy = ((y + yn) * c).sum() / (6.0 * area)
    Jo = ((x * x + x * xn + xn * xn + y * y + y * yn + yn * yn) * c).sum() / 12.0
    J = Jo - area * (cx * cx + cy * cy)
    return float(area), np.array([cx + x0[0], cy + x0[1]]), float(J)


#: Largest coordinate magnitude accepted (second moments scale with its 4th power).
MAX_COORDINATE = 1e60


def validate_outline(vertices, name: str = "polygon") -> np.ndarray:
    """Check that ``vertices`` is a finite, convex, counter-clockwise outline.

    Parameters
    ----------
    vertices
        Array-like of shape ``(2, N)``, ``N >= 3``.
    name
        Used in error messages, e.g. ``"particles[3]"``.

    Returns
    -------
    numpy.ndarray
        The vertices as a float ``(2, N)`` array (a copy).

    Raises
    ------
    ValueError
        Naming ``name``, the offending field and the allowed range.
    """
    try:
        V = np.array(vertices, dtype=float)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{name}.vertices: must be a numeric (2, N) array ({err})") from None
    if V.ndim == 2 and np.all(np.isfinite(V)) and np.abs(V).max(initial=0.0) >= MAX_COORDINATE:
        raise ValueError(f"{name}.vertices: coordinates up to {np.abs(V).max():.3g}; must be "
                         f"< {MAX_COORDINATE:g} in magnitude (areas and inertias overflow beyond)")
    if V.ndim != 2 or V.shape[0] != 2 or V.shape[1] < 3:
        raise ValueError(
            f"{name}.vertices has shape {V.shape}: must be (2, N) with N >= 3 "
            "(row 0 the x, row 1 the y coordinates)"
        )
    if not np.all(np.isfinite(V)):
        k = int(np.nonzero(~np.all(np.isfinite(V), axis=0))[0][0])
        raise ValueError(f"{name}.vertices[:, {k}] = {V[:, k]}: must be finite")
    e = np.roll(V, -1, axis=1) - V
    length = np.hypot(e[0], e[1])
    scale = float(np.max(np.ptp(V, axis=1)))
    if scale == 0.0 or np.any(length <= GEOMETRY_RTOL * scale):
        k = int(np.argmin(length))
        raise ValueError(
            f"{name}.vertices[:, {k}] and [:, {(k + 1) % V.shape[1]}] coincide: "
            "edges must have length > 0 (non-degenerate polygon)"
        )
    area = polygon_area(V)
    if area <= GEOMETRY_RTOL * scale**2:
        raise ValueError(
            f"{name} has signed area {area:.6g}: must be > 0 "
            "(vertices counter-clockwise, polygon not degenerate)"
        )
    en = np.roll(e, -1, axis=1)
    turn = (e[0] * en[1] - e[1] * en[0]) / (length * np.roll(length, -1))
    if np.any(turn <= GEOMETRY_RTOL):
        k = (int(np.argmin(turn)) + 1) % V.shape[1]
        raise ValueError(
            f"{name}.vertices[:, {k}] = {V[:, k]}: polygon must be strictly convex "
            f"(turn sine {turn.min():.3g} at this vertex, must be > 0)"
        )
    # a convex turning sequence that winds more than once is a star polygon
    winding = np.sum(np.arctan2(e[0] * en[1] - e[1] * en[0], (e * en).sum(axis=0)))
    if abs(winding - 2 * np.pi) > 1e-6:
        raise ValueError(f"{name}: outline winds {winding / (2 * np.pi):.3g} times: must be 1")
    return V


class Polygon:
    """A convex polygon (the *shadow* outline of a particle, or a wall).

    Parameters
    ----------
    vertices
        ``(2, N)`` counter-clockwise vertices of a strictly convex polygon.
    name
        Name used in error messages.

    Examples
    --------
    >>> sq = Polygon([[0.0, 1.0, 1.0, 0.0], [0.0, 0.0, 1.0, 1.0]])
    >>> float(sq.area), sq.centroid.tolist()
    (1.0, [0.5, 0.5])
    """

    def __init__(self, vertices, name: str = "polygon"):
        self.vertices = validate_outline(vertices, name)
        self.vertices.setflags(write=False)
        area, centroid, J = polygon_properties(self.vertices)
        self.area = area
        self.centroid = centroid
        self.second_moment = J

    @classmethod
    def regular(cls, n: int, radius: float, center=(0.0, 0.0), angle: float = 0.0) -> Polygon:
        """Regular ``n``-gon with circumradius ``radius``.

        Parameters
        ----------
        n
            Number of vertices, ``n >= 3``.
        radius
            Circumradius (distance centre-vertex), ``> 0``.
        center
            Centre ``(x, y)``.
        angle
            Angle of the first vertex (radians, from the x axis).
        """
        if int(n) != n or n < 3:
            raise ValueError(f"Polygon.regular n = {n}: must be an integer >= 3")
        if not (np.isfinite(radius) and 0 < radius < MAX_COORDINATE):
            raise ValueError(f"Polygon.regular radius = {radius}: must be finite, > 0 and "
                             f"< {MAX_COORDINATE:g} (areas and inertias overflow beyond)")
        phi = angle + 2.0 * np.pi * np.arange(int(n)) / int(n)
        c = np.asarray(center, dtype=float)
        return cls(np.vstack([c[0] + radius * np.cos(phi), c[1] + radius * np.sin(phi)]))

    @classmethod
    def rectangle(cls, x0: float, y0: float, x1: float, y1: float) -> Polygon:
        """Axis-aligned rectangle ``[x0, x1] x [y0, y1]``."""
        return cls([[x0, x1, x1, x0], [y0, y0, y1, y1]], name=f"rectangle({x0}, {y0}, {x1}, {y1})")

    @property
    def n(self) -> int:
        """Number of vertices."""
        return self.vertices.shape[1]

    @property
    def bounding_radius(self) -> float:
        """Largest distance from the centroid to a vertex."""
        d = self.vertices - self.centroid[:, None]
        return float(np.sqrt((d * d).sum(axis=0)).max())

    def translated(self, offset) -> Polygon:
        """The polygon moved by ``offset = (dx, dy)``."""
        return Polygon(self.vertices + np.asarray(offset, dtype=float)[:, None])

    def rotated(self, angle: float, about=None) -> Polygon:
        """The polygon rotated by ``angle`` about ``about`` (default: centroid)."""
        p = self.centroid if about is None else np.asarray(about, dtype=float)
        c, s = np.cos(angle), np.sin(angle)
        d = self.vertices - p[:, None]
        return Polygon(np.vstack([c * d[0] - s * d[1], s * d[0] + c * d[1]]) + p[:, None])

    def scaled(self, ratio: float) -> Polygon:
        """The polygon scaled by ``ratio`` about its centroid (``0 < ratio <= 1``)."""
        if not (np.isfinite(ratio) and 0.0 < ratio <= 1.0):
            raise ValueError(f"core ratio = {ratio}: must be in (0, 1]")
        c = self.centroid[:, None]
        return Polygon(c + ratio * (self.vertices - c))

    def offset(self, distance: float) -> Polygon:
        """The polygon with every edge moved inwards by ``distance >= 0``.

        Adjacent offset edges are intersected; raises ``ValueError`` when the
        distance is so large that an edge would vanish.
        """
        if not (np.isfinite(distance) and distance >= 0.0):
            raise ValueError(f"core offset = {distance}: must be finite and >= 0")
        if distance == 0.0:
            return self
        V = self.vertices
        e = np.roll(V, -1, axis=1) - V
        e = e / np.hypot(e[0], e[1])
        nrm = np.vstack([-e[1], e[0]])  # inward normal of a ccw polygon
        P = V + distance * nrm  # a point on each offset edge (edge k from vertex k)
        # vertex k is the intersection of offset edge k-1 and offset edge k
        Pp, ep = np.roll(P, 1, axis=1), np.roll(e, 1, axis=1)
        den = ep[0] * e[1] - ep[1] * e[0]
        d = P - Pp
        t = (d[0] * e[1] - d[1] * e[0]) / den
        W = Pp + t * ep
        # an edge vanishes if its offset endpoints reverse direction
        en = np.roll(W, -1, axis=1) - W
        if np.any((en * e).sum(axis=0) <= 0.0):
            raise ValueError(
                f"core offset = {distance}: too large for this polygon (an edge vanishes); "
                "must be smaller than the inradius"
            )
        return Polygon(W)

    def core(self, ratio: float | None = None, offset: float | None = None) -> Polygon:
        """Core outline: scaled by ``ratio`` or offset inwards by ``offset``."""
        if ratio is not None and offset is not None:
            raise ValueError("core: give either ratio or offset, not both")
        if offset is not None:
            return self.offset(offset)
        return self.scaled(1.0 if ratio is None else ratio)

    def __repr__(self) -> str:
        return f"Polygon(n={self.n}, area={self.area:.6g}, centroid={self.centroid.tolist()})"
