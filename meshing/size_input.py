"""A size given from outside (e.g. from a flow indicator): validation and interpolation.

``field_mesh(..., size=...)`` takes a target edge length besides its own rule, as
a callable ``size(x) -> (M,)`` for points ``x`` ``(2, M)``, or as values at points,
``(points (2, N), values (N,))``, interpolated linearly over their Delaunay
triangulation (the nearest value outside its hull). The mesh's size is then
``min(rule, max(size, h_floor))``: never finer than the smallest outline edge, so
the element count stays bounded (and checked against ``max_elements``). Nothing
here knows where the values come from.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import cast

import numpy as np
from numpy.typing import NDArray


def graded_values(points: NDArray[np.float64], values: NDArray[np.float64],
                  slope: float) -> NDArray[np.float64]:
    """Sizes limited to grow by at most ``slope`` per unit distance:
    ``h_i = min_j (values_j + slope |x_i - x_j|)`` (in blocks of rows)."""
    out = values.copy()
    for a in range(0, points.shape[1], 512):
        d = np.hypot(points[0, a:a + 512, None] - points[0, None, :],
                     points[1, a:a + 512, None] - points[1, None, :])
        out[a:a + 512] = np.min(values[None, :] + slope * d, axis=1)
    return out


class PointSize:
    """Linear interpolation of sizes given at points (nearest value outside their hull),
    graded first so that they grow by at most ``slope`` per unit distance.

    Parameters
    ----------
    points : (2, N) array
    values : (N,) array, finite and > 0
    slope : float or None
        Largest growth of the size per unit distance (None: as given). A size
        that jumps faster than the mesh's own grading leaves triangles outside
        the quality bounds (a flow-graded wake mesh reached 14.5 deg without it).
    """

    def __init__(self, points: NDArray[np.float64], values: NDArray[np.float64],
                 slope: float | None = None) -> None:
        from scipy.interpolate import LinearNDInterpolator, NearestNDInterpolator

        if slope is not None:
            values = graded_values(points, values, slope)
        self.points, self.values = points, values
        self._linear = LinearNDInterpolator(points.T, values)
        self._nearest = NearestNDInterpolator(points.T, values)

    def __call__(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        h = self._linear(x.T)
        out = np.isnan(h)
        if np.any(out):
            h[out] = self._nearest(x[:, out].T)
        return h


def _checked(fn: Callable) -> Callable:
    """``fn`` with its output checked: ``(M,)`` finite numbers > 0."""

    def size(x: NDArray[np.float64]) -> NDArray[np.float64]:
        try:
            h = np.asarray(fn(x), dtype=float)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"size: the callable failed on points (2, {x.shape[1]}): {exc}"
                             ) from None
        if h.shape != (x.shape[1],):
            raise ValueError(f"size: the callable must return shape ({x.shape[1]},) for "
                             f"points (2, {x.shape[1]}), got {h.shape}")
        if not np.all(np.isfinite(h) & (h > 0.0)):
            raise ValueError("size: the callable must return finite sizes > 0")
        return h

    return size


def as_size(size: object, slope: float | None = None) -> Callable | None:
    """A checked size callable from ``size`` (None, a callable, or ``(points, values)``,
    graded to grow by at most ``slope`` per unit distance)."""
    if size is None:
        return None
    if callable(size):
        return _checked(size)
    try:
        points, values = cast(tuple, size)
        P = np.array(points, dtype=np.float64)
        v = np.array(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError("size: expected a callable size(x) -> (M,) or (points (2, N), "
                         "values (N,))") from None
    if P.ndim != 2 or P.shape[0] != 2 or P.shape[1] < 3 or v.shape != (P.shape[1],):
        raise ValueError(f"size: points must be (2, N) with N >= 3 and values (N,), got "
                         f"{P.shape} and {v.shape}")
    if not (np.all(np.isfinite(P)) and np.all(np.isfinite(v)) and np.all(v > 0.0)):
        raise ValueError("size: points must be finite and values finite and > 0")
    return PointSize(P, v, slope)
