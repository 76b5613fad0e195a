"""Prescribed (imposed) rigid motions: particles moved along a given trajectory.

A particle with a :class:`PrescribedMotion` is *kinematic*: no force integrates
it. Its pose ``q = (x, y, angle)`` at every step time is the motion's, and its
velocity ``(vx, vy, omega)`` over a step is the BDF2 derivative of its poses
(:func:`pose_derivative`), the same relation by which a free particle's pose
follows from its velocity (:mod:`skfem_granular.dem.integrator`,
:mod:`skfem_granular.coupled.stepper`). That derivative is exact for motions of
constant velocity or constant acceleration, second order otherwise, and a
trajectory recorded from a free run (poses at its step times) replayed with the
same steps gives back that run's velocities to round-off.

Three kinds, one class:

- constant velocity: ``PrescribedMotion(velocity=(U, V), omega=w)``, poses
  ``q(t) = q(0) + (U, V, w) t`` from where the particle starts;
- a table ``PrescribedMotion(trajectory=T)`` with ``T`` a ``(4, n)`` array whose
  rows are ``t, x, y, angle`` (``n >= 2`` samples, ``t`` increasing; e.g. the
  ``t, x, y, angle`` columns of a run's history with the start ``(0, x0, y0, 0)``
  prepended), interpolated by a cubic spline (not-a-knot; exact at the samples);
- a function ``PrescribedMotion(trajectory=f)``, ``f(t) -> (x, y, angle)``
  (Python only: a function cannot go into a checkpoint).

A table or a function gives absolute poses: it must start at the particle's
pose (its centroid, angle 0) at ``t = 0`` (:meth:`PrescribedMotion.check_start`).
The one value poses do not determine, the velocity at ``t = 0``, is
:meth:`PrescribedMotion.initial_velocity`: the constant velocity, or the
particle's own ``velocity``/``angular_velocity`` for a table or a function
(default: at rest, as a recorded run starts).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..timestep import BDF2

__all__ = ["PrescribedMotion", "pose_derivative"]


def pose_derivative(q_new: np.ndarray, q_n: np.ndarray, q_prev, dt: float,
                    dt_prev: float | None) -> np.ndarray:
    """BDF2 derivative ``a0 q_{n+1} + a1 q_n + a2 q_{n-1}`` of poses (backward Euler
    without ``dt_prev``): the velocity of a particle that moves along prescribed poses.

    Parameters
    ----------
    q_new, q_n : ndarray
        Poses ``(3, ...)`` at ``t_{n+1}`` and ``t_n``.
    q_prev : ndarray or None
        Poses at ``t_{n-1}`` (unused without ``dt_prev``).
    dt, dt_prev : float
        The step and the one before it (None: backward Euler).
    """
    return BDF2(dt, dt_prev).derivative(q_new, q_n, q_prev)


def _finite(where: str, value, n: int) -> tuple:
    try:
        x = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{where} = {value!r}: must be {n} finite numbers") from None
    if isinstance(value, bool) or x.size != n or not np.all(np.isfinite(x)):
        raise ValueError(f"{where} = {value!r}: must be {n} finite numbers")
    return tuple(float(v) for v in x)


@dataclass(frozen=True, eq=False)
class PrescribedMotion:
    """An imposed rigid motion of one particle (module notes: the three kinds).

    Parameters
    ----------
    velocity : (2,) tuple
        Constant velocity ``(U, V)`` of the centroid (m/s).
    omega : float
        Constant angular velocity (rad/s, counter-clockwise).
    trajectory : (4, n) array_like or callable, optional
        Instead of a constant velocity: a table whose rows are ``t, x, y, angle``
        (``n >= 2``, ``t`` strictly increasing), or a function ``t -> (x, y,
        angle)``. With a trajectory, ``velocity`` and ``omega`` stay 0.

    Raises
    ------
    ValueError
        One line naming the field (``motion.velocity``, ``motion.trajectory``) and
        what it must be.

    Examples
    --------
    >>> PrescribedMotion(velocity=(2e-3, 0.0)).kind
    'constant'
    >>> m = PrescribedMotion(trajectory=[[0.0, 1.0], [0.0, 1.0], [0.0, 0.0], [0.0, 0.0]])
    >>> m.pose(0.5).tolist()
    [0.5, 0.0, 0.0]
    """

    velocity: tuple = (0.0, 0.0)
    omega: float = 0.0
    trajectory: ArrayLike | Callable[[float], ArrayLike] | None = None

    def __post_init__(self):
        object.__setattr__(self, "velocity", _finite("motion.velocity", self.velocity, 2))
        omega = self.omega
        if isinstance(omega, bool) or not np.isfinite(_scalar("motion.omega", omega)):
            raise ValueError(f"motion.omega = {omega!r}: must be a finite number")
        object.__setattr__(self, "omega", float(omega))
        traj = self.trajectory
        if traj is None:
            return
        if self.velocity != (0.0, 0.0) or self.omega != 0.0:
            raise ValueError("motion: give a constant velocity/omega or a trajectory, not both "
                             f"(velocity = {list(self.velocity)}, omega = {self.omega:g})")
        if callable(traj):
            return
        try:
            T = np.array(traj, dtype=float)
        except (TypeError, ValueError):
            raise ValueError("motion.trajectory: must be a (4, n) array of numbers (rows t, x, "
                             "y, angle) or a function t -> (x, y, angle)") from None
        if T.ndim != 2 or T.shape[0] != 4 or T.shape[1] < 2:
            raise ValueError(f"motion.trajectory has shape {T.shape}: must be (4, n) with n >= 2 "
                             "(rows t, x, y, angle)")
        if not np.all(np.isfinite(T)):
            raise ValueError("motion.trajectory: contains NaN or inf (must be finite)")
        if not np.all(np.diff(T[0]) > 0):
            k = int(np.flatnonzero(np.diff(T[0]) <= 0)[0])
            raise ValueError(f"motion.trajectory: times must increase strictly (t[{k}] = "
                             f"{T[0, k]:g}, t[{k + 1}] = {T[0, k + 1]:g})")
        T.flags.writeable = False
        object.__setattr__(self, "trajectory", T)

    # ------------------------------------------------------------------ kinds
    @property
    def kind(self) -> str:
        """``"constant"``, ``"table"`` or ``"function"``."""
        if self.trajectory is None:
            return "constant"
        return "function" if callable(self.trajectory) else "table"

    def __eq__(self, other):
        if not isinstance(other, PrescribedMotion) or self.kind != other.kind:
            return NotImplemented if not isinstance(other, PrescribedMotion) else False
        if self.kind == "table":
            return bool(np.array_equal(self.trajectory, other.trajectory))
        if self.kind == "function":
            return self.trajectory is other.trajectory
        return self.velocity == other.velocity and self.omega == other.omega

    # no __hash__: a class defining __eq__ gets __hash__ = None (unhashable, as a table is)

    def _table(self) -> np.ndarray:
        """The ``(4, n)`` table of the kind ``"table"`` (stored read-only by ``__post_init__``)."""
        T = self.trajectory
        assert isinstance(T, np.ndarray)
        return T

    @property
    def span(self) -> tuple[float, float]:
        """The times the motion is defined for (a table's first and last; else all)."""
        if self.kind == "table":
            T = self._table()
            return float(T[0, 0]), float(T[0, -1])
        return -np.inf, np.inf

    # ------------------------------------------------------------------ poses
    def _spline(self):
        s = self.__dict__.get("_cached_spline")
        if s is None:
            from scipy.interpolate import CubicSpline

            T = self._table()
            s = CubicSpline(T[0], T[1:], axis=1)
            object.__setattr__(self, "_cached_spline", s)
        return s

    def pose(self, t: float, start=None) -> np.ndarray:
        """Pose ``(x, y, angle)`` ``(3,)`` at time ``t``.

        Parameters
        ----------
        t : float
        start : (3,) array_like
            The pose at ``t = 0`` (needed by the constant kind only).

        Raises
        ------
        ValueError
            ``t`` outside a table, or a function returning something else than three
            finite numbers.
        """
        t = float(t)
        kind = self.kind
        if kind == "constant":
            if start is None:
                raise ValueError("motion.pose: a constant motion needs the start pose")
            return np.asarray(start, dtype=float).reshape(3) + t * np.array(
                [self.velocity[0], self.velocity[1], self.omega])
        if kind == "table":
            t0, t1 = self.span
            tol = 1e-9 * max(t1 - t0, abs(t0), abs(t1))
            if not (t0 - tol <= t <= t1 + tol):
                raise ValueError(f"motion.trajectory: t = {t:.6g} s lies outside the table "
                                 f"[{t0:.6g}, {t1:.6g}] s")
            T = self._table()
            k = np.searchsorted(T[0], t)
            if k < T.shape[1] and T[0, k] == t:  # a sample: its pose, bit for bit
                return T[1:, k].copy()
            return np.asarray(self._spline()(min(max(t, t0), t1)), dtype=float)
        f = self.trajectory
        assert callable(f)  # the kind "function"
        try:
            q = np.asarray(f(t), dtype=float).reshape(-1)
        except (TypeError, ValueError):
            q = np.zeros(0)
        if q.size != 3 or not np.all(np.isfinite(q)):
            raise ValueError(f"motion.trajectory({t:.6g}): must return 3 finite numbers "
                             "(x, y, angle)")
        return q

    def initial_velocity(self, velocity=(0.0, 0.0), angular_velocity: float = 0.0) -> np.ndarray:
        """Velocity ``(vx, vy, omega)`` at ``t = 0``: the constant one, or else the given one."""
        if self.kind == "constant":
            return np.array([self.velocity[0], self.velocity[1], self.omega])
        return np.array([float(velocity[0]), float(velocity[1]), float(angular_velocity)])

    # ------------------------------------------------------------------ checks
    def check_start(self, where: str, start, radius: float) -> None:
        """Refuse a table or function that does not start at the particle's pose.

        Parameters
        ----------
        where : str
            The particle's name in errors (``"particles[0]"``).
        start : (3,) array_like
            The particle's pose at ``t = 0`` (centroid, angle 0).
        radius : float
            The particle's bounding radius (the position tolerance is ``1e-6`` of it,
            the angle's ``1e-6`` rad).
        """
        if self.kind == "constant":
            return
        t0, t1 = self.span
        if t0 > 0.0 or t1 < 0.0:
            raise ValueError(f"{where}.motion.trajectory: the table covers t in [{t0:g}, {t1:g}] "
                             "s: must include t = 0")
        try:
            q0 = self.pose(0.0)
        except ValueError as exc:
            raise ValueError(f"{where}.{exc}") from None
        s = np.asarray(start, dtype=float).reshape(3)
        if (np.hypot(q0[0] - s[0], q0[1] - s[1]) > 1e-6 * radius
                or abs(q0[2] - s[2]) > 1e-6):
            raise ValueError(f"{where}.motion.trajectory: starts at (x, y, angle) = "
                             f"({q0[0]:.9g}, {q0[1]:.9g}, {q0[2]:.6g}) at t = 0, not at the "
                             f"particle's pose ({s[0]:.9g}, {s[1]:.9g}, {s[2]:.6g})")

    def reach(self, t_end: float, start, radius: float) -> float:
        """Largest distance a point of the particle gets from where it starts within
        ``[0, t_end]`` (centroid travel plus ``radius`` times the largest rotation), sampled."""
        s = np.asarray(start, dtype=float).reshape(3)
        ts = np.linspace(0.0, float(t_end), 257)
        if self.kind == "table":
            T = self._table()[0]
            ts = np.union1d(ts, T[(T >= 0.0) & (T <= t_end)])
            ts = ts[(ts >= self.span[0]) & (ts <= self.span[1])]
        q = np.array([self.pose(t, s) for t in ts]).T
        d = np.hypot(q[0] - s[0], q[1] - s[1]) + radius * np.abs(q[2] - s[2])
        return float(d.max(initial=0.0))


def _scalar(where: str, value) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{where} = {value!r}: must be a finite number") from None
