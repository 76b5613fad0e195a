"""Period, amplitude and Strouhal number of an oscillating record (a particle's wake).

Used for the lateral oscillation of a disk settling at moderate Reynolds numbers: the
extrema of the offset, one per half cycle, refined by a parabola through the samples.
"""

from __future__ import annotations

import numpy as np


def extrema(t: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The extrema of an oscillation ``y(t)``, one per half cycle.

    The half cycles are split by the crossings of the mean of ``y``; each one's extremum
    is its largest ``|y - mean|``, refined by the parabola through it and its two
    neighbours. The partial half cycles at either end count only if their extremum
    lies inside them (a turning point, not the end of the record). Returns times
    ``(n,)`` and values ``(n,)``, alternating maxima and minima."""
    t, y = np.asarray(t, dtype=float), np.asarray(y, dtype=float)
    m = float(y.mean())
    s = np.sign(y - m)
    cross = np.flatnonzero(s[1:] * s[:-1] < 0) + 1        # first sample after a crossing
    bounds = np.concatenate([[0], cross, [y.size]])
    te, ye = [], []
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        k = a + int(np.argmax(np.abs(y[a:b] - m)))
        if k == 0 or k == y.size - 1:                     # the record's end, not a turn
            continue
        c = np.polyfit(t[k - 1:k + 2] - t[k], y[k - 1:k + 2], 2)
        tk = -c[1] / (2.0 * c[0]) if c[0] != 0.0 else 0.0
        tk = tk if abs(tk) <= t[k + 1] - t[k] else 0.0
        te.append(t[k] + tk)
        ye.append(float(np.polyval(c, tk)))
    return np.array(te), np.array(ye)


def oscillation(t: np.ndarray, dx: np.ndarray, vy: np.ndarray, d: float,
                window: tuple[float, float] = (0.65, 1.04)) -> dict:
    """Period, amplitude and Strouhal number of the lateral oscillation in ``window``.

    From the :func:`extrema` of the lateral offset ``dx(t)`` within ``window`` (s):
    ``period`` the mean of the mean time between successive maxima and that between
    successive minima, ``periods`` the shortest and longest of those times,
    ``amplitude`` half the mean maximum minus the mean minimum (half the peak-to-peak),
    ``mean`` the mean of those two (the offset the disk oscillates about), ``U`` the
    mean fall speed ``|vy|`` and ``strouhal = d / (period U)`` (``d`` the diameter)."""
    t, dx, vy = (np.asarray(a, dtype=float) for a in (t, dx, vy))
    w = (t >= window[0]) & (t <= window[1])
    te, ye = extrema(t[w], dx[w])
    hi = ye > np.mean(ye)
    if hi.sum() < 2 or (~hi).sum() < 2:
        raise ValueError(f"window = {window}: {hi.sum()} maxima and {(~hi).sum()} minima of "
                         "the offset, at least 2 of each needed for a period")
    full = np.concatenate([np.diff(te[hi]), np.diff(te[~hi])])
    period = 0.5 * (np.diff(te[hi]).mean() + np.diff(te[~hi]).mean())
    U = float(np.abs(vy[w]).mean())
    return {"period": float(period), "periods": [float(full.min()), float(full.max())],
            "amplitude": float(0.5 * (ye[hi].mean() - ye[~hi].mean())),
            "mean": float(0.5 * (ye[hi].mean() + ye[~hi].mean())),
            "extrema": int(te.size), "U": U, "strouhal": float(d / (period * U))}
