"""Solid fraction of a packing: exact area of grain outlines inside a rectangular window.

Each convex outline is clipped to the window (Sutherland-Hodgman against the four
sides), so grains cut by the window count with the part inside it.
"""

from __future__ import annotations

import numpy as np

from ..dem.polygon import polygon_area

__all__ = ["clipped_area", "solid_fraction"]


def _clip(P: np.ndarray, axis: int, value: float, keep_below: bool) -> np.ndarray:
    """The part of the convex outline ``P`` (2, k) on one side of ``x[axis] = value``."""
    if P.shape[1] == 0:
        return P
    s = P[axis] - value
    inside = s <= 0 if keep_below else s >= 0
    out = []
    k = P.shape[1]
    for i in range(k):
        j = (i + 1) % k
        if inside[i]:
            out.append(P[:, i])
        if inside[i] != inside[j]:
            t = s[i] / (s[i] - s[j])
            out.append(P[:, i] + t * (P[:, j] - P[:, i]))
    return np.array(out).T if out else np.zeros((2, 0))


def clipped_area(outline: np.ndarray, window) -> float:
    """Area of the convex ``outline`` (2, k) inside ``window = (x0, y0, x1, y1)``."""
    x0, y0, x1, y1 = window
    P = np.asarray(outline, dtype=float)
    if P[0].min() >= x0 and P[0].max() <= x1 and P[1].min() >= y0 and P[1].max() <= y1:
        return polygon_area(P)
    if P[0].max() <= x0 or P[0].min() >= x1 or P[1].max() <= y0 or P[1].min() >= y1:
        return 0.0
    for axis, value, below in ((0, x0, False), (0, x1, True), (1, y0, False), (1, y1, True)):
        P = _clip(P, axis, value, below)
    return polygon_area(P)


def solid_fraction(outlines, window) -> float:
    """Grain area inside ``window = (x0, y0, x1, y1)`` over the window's area.

    Parameters
    ----------
    outlines : sequence of (2, k) arrays
        Convex counter-clockwise outlines (the shadows: the grains' contact outlines).
    window : (x0, y0, x1, y1)
        The measuring window, with x1 > x0 and y1 > y0.
    """
    x0, y0, x1, y1 = (float(v) for v in window)
    if not (x1 > x0 and y1 > y0):
        raise ValueError(f"window = {tuple(window)}: must be (x0, y0, x1, y1) with x1 > x0, "
                         "y1 > y0")
    return sum(clipped_area(P, (x0, y0, x1, y1)) for P in outlines) / ((x1 - x0) * (y1 - y0))
