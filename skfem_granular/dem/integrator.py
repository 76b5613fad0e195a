"""BDF2 predictor-corrector (Gear) for rigid bodies, variable step size.

The state is ``q = (x, y, angle)`` and ``v = (vx, vy, omega)``, both
``(3, N)``. One step of size ``dt`` (previous step ``dt_prev``,
``w = dt / dt_prev``):

1. *predict* (explicit, second order):
   ``q* = q_n + dt v_n + dt^2/2 a_n``,
   ``v* = v_n + dt ((1 + w/2) a_n - (w/2) a_{n-1})`` (Adams-Bashforth 2);
2. *evaluate* the accelerations ``a* = a(q*, v*)`` (forces / masses);
3. *correct* with variable-step BDF2 (:func:`skfem_granular.timestep.bdf2_coefficients`)
   ``a0 y_{n+1} + a1 y_n + a2 y_{n-1} = f_{n+1}``, first for ``v``
   (``f = a*``), then for ``q`` (``f = v_{n+1}``).

The first step has no history: ``v_1 = v_0 + dt a*`` and the trapezoidal
rule ``q_1 = q_0 + dt (v_0 + v_1) / 2`` (exact for constant acceleration, so
free flight is reproduced to round-off). One force evaluation per step (PEC
mode); the scheme is second order.
"""

from __future__ import annotations

import numpy as np

from ..timestep import BDF2, bdf2_coefficients

__all__ = ["BDF2History", "bdf2_coefficients", "correct", "predict", "stable_time_step"]


def stable_time_step(mass: np.ndarray, E: float, gamma: float = 0.0,
                     factor: float = 0.1) -> float:
    """Stable step estimate ``factor * pi * sqrt(min m / E) / max(1, 2 gamma)``.

    ``factor * pi * sqrt(min m / E)`` is the bound of Matuttis & Chen. The
    predictor-corrector treats the velocity-dependent damping explicitly; in
    dense packings (several contacts per particle) it became unstable for
    ``gamma = 1`` at that bound and was stable at half of it, hence the
    empirical divisor ``max(1, 2 gamma)``.
    """
    if mass.size == 0:
        return np.inf
    return float(factor * np.pi * np.sqrt(mass.min() / E) / max(1.0, 2.0 * gamma))


class BDF2History:
    """History the BDF2 scheme needs besides the current ``q``, ``v``.

    Attributes
    ----------
    q_prev, v_prev
        State at the previous step (``None`` before the first step).
    a, a_prev
        Accelerations at the current and the previous step.
    dt_prev
        Size of the last step (``None`` before the first step).
    """

    def __init__(self):
        self.q_prev = None
        self.v_prev = None
        self.a = None
        self.a_prev = None
        self.dt_prev = None

    def as_dict(self) -> dict:
        """Copies of all arrays (``None`` entries kept), for checkpoints."""
        return {k: (None if v is None else np.array(v, copy=True))
                for k, v in vars(self).items()}

    @classmethod
    def from_dict(cls, d: dict) -> BDF2History:
        """Inverse of :meth:`as_dict`."""
        h = cls()
        for k in vars(h):
            v = d.get(k)
            setattr(h, k, None if v is None else np.array(v, copy=True))
        if h.dt_prev is not None:
            h.dt_prev = float(h.dt_prev)
        return h


def predict(q, v, hist: BDF2History, dt: float):
    """Explicit second-order predictor ``(q*, v*)`` (needs ``hist.a``)."""
    a = hist.a
    qp = q + dt * v + 0.5 * dt * dt * a
    if hist.a_prev is None or hist.dt_prev is None:
        vp = v + dt * a
    else:
        w = dt / hist.dt_prev
        vp = v + dt * ((1.0 + 0.5 * w) * a - 0.5 * w * hist.a_prev)
    return qp, vp


def correct(q, v, hist: BDF2History, a_star, dt: float):
    """BDF2 corrector; returns the new ``(q, v)`` and updates ``hist`` in place.

    Parameters
    ----------
    q, v
        ``(3, N)`` current state (not modified).
    hist
        History; afterwards it describes the new state.
    a_star
        ``(3, N)`` accelerations evaluated at the predicted state.
    dt
        Step size.
    """
    if hist.q_prev is None or hist.dt_prev is None:
        v_new = v + dt * a_star
        q_new = q + 0.5 * dt * (v + v_new)
    else:
        f = BDF2(dt, hist.dt_prev)
        v_new = f.solve(a_star, v, hist.v_prev)
        q_new = f.solve(v_new, q, hist.q_prev)
    hist.q_prev = q.copy()
    hist.v_prev = v.copy()
    hist.a_prev = hist.a
    hist.a = a_star
    hist.dt_prev = dt
    return q_new, v_new
