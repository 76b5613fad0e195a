"""Quantities the sedimentation benchmarks read off a run (checks 2-6).

Every function takes plain arrays (a run's ``history`` columns, or final
positions), so that each is tested on synthetic data with a known answer
(``tests/test_sedimentation.py``). SI units; velocities are signed (settling
is ``vy < 0``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["angle_of_repose", "axis_orientation", "kiss_tumble_times", "lateral_offset",
           "particle_reynolds", "settled_after", "settling_summary", "velocity_plateau"]


def particle_reynolds(vx, vy, d: float, rho_f: float, mu: float) -> np.ndarray:
    """``Re_p = rho_f |v| d / mu`` at every step (``vx``, ``vy`` arrays of equal shape)."""
    return rho_f * np.hypot(np.asarray(vx, float), np.asarray(vy, float)) * d / mu


def velocity_plateau(t, v, rel_tol: float = 2e-3) -> dict:
    """The velocity plateau of a settling run: where ``|v|`` is within ``rel_tol`` of its peak.

    Parameters
    ----------
    t, v : (T,) arrays
        Times and one velocity component (or speed); the sign is kept.
    rel_tol : float
        Width of the plateau band relative to the peak ``max |v|``.

    Returns
    -------
    dict
        ``peak`` (signed ``v`` at ``max |v|``), ``t_peak``, ``plateau`` (mean of
        ``v`` over the contiguous band around the peak), ``t_start``,
        ``t_end`` (the band's extent) and ``duration``; ``reached`` is True
        when the band lasts at least a fifth of the time before it (a short
        band is only a turning point, not a plateau).
    """
    t = np.asarray(t, float)
    v = np.asarray(v, float)
    if t.size == 0:
        raise ValueError("velocity_plateau: empty history")
    s = np.abs(v)
    k = int(np.argmax(s))
    band = s >= (1.0 - rel_tol) * s[k]
    lo = k
    while lo > 0 and band[lo - 1]:
        lo -= 1
    hi = k
    while hi < t.size - 1 and band[hi + 1]:
        hi += 1
    duration = float(t[hi] - t[lo])
    return {"peak": float(v[k]), "t_peak": float(t[k]), "plateau": float(v[lo:hi + 1].mean()),
            "t_start": float(t[lo]), "t_end": float(t[hi]), "duration": duration,
            "reached": bool(hi > lo and duration >= 0.2 * (t[lo] - t[0]))}


def settling_summary(t, x, y, vx, vy, d: float, rho_f: float, mu: float,
                     rel_tol: float = 2e-3) -> dict:
    """Check 2's numbers for one particle: maximum ``Re_p``, the plateau, the trajectory.

    Returns ``re_max``, ``t_re_max``, ``v_max`` (signed ``vy`` there),
    ``plateau`` (:func:`velocity_plateau` of ``vy``), ``re_plateau``, the
    final position and the largest sideways drift ``max |x - x(0)|``.
    """
    t, x, y, vx, vy = (np.asarray(a, float) for a in (t, x, y, vx, vy))
    re = particle_reynolds(vx, vy, d, rho_f, mu)
    k = int(np.argmax(re))
    pl = velocity_plateau(t, vy, rel_tol)
    return {"re_max": float(re[k]), "t_re_max": float(t[k]), "v_max": float(vy[k]),
            "plateau": pl, "re_plateau": float(rho_f * abs(pl["plateau"]) * d / mu),
            "x_final": float(x[-1]), "y_final": float(y[-1]),
            "max_drift": float(np.abs(x - x[0]).max())}


def kiss_tumble_times(t, x, y, radius: float, kiss_gap: float = 0.0,
                      draft_rel: float = 0.01) -> dict:
    """Drafting, kissing and tumbling of two disks, from their centre histories.

    Parameters
    ----------
    t : (T,)
    x, y : (T, 2)
        Centre coordinates of the two particles.
    radius : float
        Contact radius of each disk (the shadow's): the gap is
        ``|x_1 - x_0| - 2 radius``.
    kiss_gap : float
        The pair *kisses* when the gap first falls to ``kiss_gap`` or below
        (0: shadows touch).
    draft_rel : float
        Drafting: the trailing disk falls faster than the leading one by more
        than ``draft_rel`` of the leading disk's speed.

    Returns
    -------
    dict
        ``t_drafting`` (first time the drafting criterion holds; velocities
        by central differences of ``y``), ``t_kiss`` (first time
        ``gap <= kiss_gap``; NaN if never), ``min_gap`` and ``t_min_gap``,
        ``t_tilt45`` (first time after the kiss that the line of centres is
        45 degrees or more from the vertical), ``t_tumble`` (first time after
        the kiss that the pair's vertical order swaps, the line of centres
        passing the horizontal), each NaN if never; ``stages`` (True when
        drafting, kissing and tumbling all happen in that order), ``gap`` and
        ``tilt`` (degrees from the vertical, trailing disk above = 0) histories.
    """
    t = np.asarray(t, float)
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    gap = np.hypot(x[:, 1] - x[:, 0], y[:, 1] - y[:, 0]) - 2.0 * radius
    lead = int(np.argmin(y[0]))  # the lower one leads
    trail = 1 - lead
    kiss = np.flatnonzero(gap <= kiss_gap)
    t_kiss = float(t[kiss[0]]) if kiss.size else float("nan")
    k_min = int(np.argmin(gap))
    tilt = np.degrees(np.arctan2(np.abs(x[:, trail] - x[:, lead]), y[:, trail] - y[:, lead]))

    def first_after_kiss(mask):
        if not kiss.size:
            return float("nan")
        k = np.flatnonzero(mask & (np.arange(t.size) >= kiss[0]))
        return float(t[k[0]]) if k.size else float("nan")

    t_tumble = first_after_kiss(tilt >= 90.0)  # the trailing disk no longer above
    t_tilt45 = first_after_kiss(tilt >= 45.0)
    vy = np.gradient(y, t, axis=0) if t.size > 1 else np.zeros_like(y)
    faster = vy[:, trail] < vy[:, lead] - draft_rel * np.abs(vy[:, lead])
    draft = np.flatnonzero(faster & (np.abs(vy[:, lead]) > 0))
    t_draft = float(t[draft[0]]) if draft.size else float("nan")
    stages = bool(np.isfinite(t_draft) and np.isfinite(t_kiss) and np.isfinite(t_tumble)
                  and t_draft <= t_kiss <= t_tumble)
    return {"t_drafting": t_draft, "t_kiss": t_kiss, "t_tilt45": t_tilt45,
            "t_tumble": t_tumble, "min_gap": float(gap[k_min]), "t_min_gap": float(t[k_min]),
            "stages": stages, "gap": gap, "tilt": tilt}


def lateral_offset(t, x, x_centre: float, half_width: float) -> dict:
    """Check 4: the offset from the centreline relative to the half-width.

    Returns ``offset`` ``(T,)`` (``|x - x_centre| / half_width``), ``initial``,
    ``final``, ``max`` and ``t_1pc`` (first time after which the offset stays
    below 1 %; NaN if it never does).
    """
    off = np.abs(np.asarray(x, float) - x_centre) / half_width
    return {"offset": off, "initial": float(off[0]), "final": float(off[-1]),
            "max": float(off.max()), "t_1pc": settled_after(t, off, 0.01)}


def settled_after(t, q, bound: float) -> float:
    """The first time after which ``q`` stays below ``bound`` to the end of the history.

    ``t[0]`` when ``q`` is below ``bound`` throughout; NaN when its last value
    is not (the history ends before ``q`` settles).
    """
    t = np.asarray(t, float)
    above = np.flatnonzero(np.asarray(q, float) >= bound)
    if above.size == 0:
        return float(t[0])
    if above[-1] == t.size - 1:
        return float("nan")
    return float(t[above[-1] + 1])


def axis_orientation(angle, axis0: float) -> np.ndarray:
    """Check 5: the long axis' angle to the horizontal, folded into ``[0, 90]`` degrees.

    ``angle`` is the history's rotation (rad) since the start, ``axis0`` the
    long axis' angle at the start (rad). 0 degrees is broadside to a
    vertical fall (long axis horizontal), 90 edgewise.
    """
    a = np.mod(np.asarray(angle, float) + axis0, np.pi)  # an axis: modulo pi
    a = np.minimum(a, np.pi - a)
    return np.degrees(a)


def angle_of_repose(x, top, column: float, lo: float = 0.2, hi: float = 0.9,
                    centre: float | None = None) -> dict:
    """Angle of repose of a heap from its grains' centres and tops.

    The free surface is the highest grain top of every ``column``-wide
    column; its points between ``lo`` and ``hi`` of the heap height are
    fitted with a straight line on each flank of the heap (left of and right
    of ``centre``, default the highest column).

    Parameters
    ----------
    x, top : (N,) arrays
        Grain centre abscissae and the heights of their tops (centre height
        plus circumradius).
    column : float
        Column width (a grain diameter).

    Returns
    -------
    dict
        ``left``, ``right`` (degrees, positive for a heap that falls away
        from the centre), ``mean``, ``height``, ``points`` per flank.
    """
    x = np.asarray(x, float)
    top = np.asarray(top, float)
    cols = np.floor(x / column).astype(int)
    pts = np.array([(x[m][np.argmax(top[m])], top[m].max())
                    for m in (cols == c for c in np.unique(cols))])
    H = pts[:, 1].max()
    c = pts[np.argmax(pts[:, 1]), 0] if centre is None else centre
    out = {"height": float(H), "centre": float(c)}
    angles = []
    for name, side in (("left", -1), ("right", 1)):
        q = pts[(side * (pts[:, 0] - c) > 0) & (pts[:, 1] > lo * H) & (pts[:, 1] < hi * H)]
        if len(q) < 2:
            out[name] = float("nan")
            out[f"{name}_points"] = int(len(q))
            continue
        slope = np.polyfit(side * (q[:, 0] - c), q[:, 1], 1)[0]
        out[name] = float(np.degrees(np.arctan(-slope)))
        out[f"{name}_points"] = int(len(q))
        angles.append(out[name])
    out["mean"] = float(np.mean(angles)) if angles else float("nan")
    return out
