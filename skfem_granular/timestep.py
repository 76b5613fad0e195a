"""Variable-step BDF2: coefficients, predictor, local error estimate, step control.

The corrected form of the paper's Eq. 1 (docs/design.md), with ``w = dt_n / dt_{n-1}``::

    du/dt(t_{n+1}) ~ a0 u_{n+1} + a1 u_n + a2 u_{n-1}
    a0 = (1 + 2w) / (dt_n (1 + w)),  a1 = -(1 + w) / dt_n,  a2 = w^2 / (dt_n (1 + w))

The predictor is the explicit second-order Adams-Bashforth formula on the
time derivatives; Milne's device turns the predictor-corrector difference
into an estimate of the corrector's local error. With the Taylor expansions
``u_c - u = Cc dt^3 u'''`` and ``u - u_p = Cp dt^3 u'''``::

    Cc = (1 + w)^2 / (6 w (1 + 2 w)),   Cp = 1/6 + 1/(4 w)
    err ~ Cc / (Cc + Cp) * (u_c - u_p)          (8/23 for w = 1)

Variable-step BDF2 is zero-stable for ``w < 1 + sqrt(2)``; the controller
caps the growth ratio below that.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ._validate import positive

#: Zero-stability limit of the step ratio for variable-step BDF2.
MAX_STABLE_RATIO = 1.0 + math.sqrt(2.0)


def bdf2_coefficients(dt: float, dt_prev: float | None) -> tuple[float, float, float]:
    """``(a0, a1, a2)`` of the variable-step BDF2 derivative.

    ``dt_prev=None`` gives backward Euler ``(1/dt, -1/dt, 0)``.

    Examples
    --------
    >>> bdf2_coefficients(0.1, 0.1)
    (15.0, -20.0, 5.0)
    """
    if dt_prev is None:
        return 1.0 / dt, -1.0 / dt, 0.0
    w = dt / dt_prev
    return (1 + 2 * w) / (dt * (1 + w)), -(1 + w) / dt, w * w / (dt * (1 + w))


@dataclass(frozen=True)
class BDF2:
    """One step's variable-step BDF2 formula (backward Euler without ``dt_prev``).

    The one place where ``a0 x_{n+1} + a1 x_n + a2 x_{n-1}`` is written: the time
    derivative of fluid velocities, rigid velocities, poses and mesh vertices alike.
    Without ``dt_prev`` the ``x_{n-1}`` term is absent and ``x_prev`` is not read.

    Parameters
    ----------
    dt : float
        The step.
    dt_prev : float or None
        The step before it (None: backward Euler).

    Examples
    --------
    >>> f = BDF2(0.1, 0.1)
    >>> f.a0, f.a1, f.a2
    (15.0, -20.0, 5.0)
    >>> f.derivative(2.0, 1.0, 0.0)   # d/dt of x = 10 t at t = 0.2
    10.0
    """

    dt: float
    dt_prev: float | None = None
    a0: float = field(init=False, repr=False)
    a1: float = field(init=False, repr=False)
    a2: float = field(init=False, repr=False)

    def __post_init__(self):
        a0, a1, a2 = bdf2_coefficients(self.dt, self.dt_prev)
        object.__setattr__(self, "a0", a0)
        object.__setattr__(self, "a1", a1)
        object.__setattr__(self, "a2", a2)

    @property
    def coefficients(self) -> tuple[float, float, float]:
        """``(a0, a1, a2)`` (:func:`bdf2_coefficients`)."""
        return self.a0, self.a1, self.a2

    @property
    def euler(self) -> bool:
        """Whether this is a backward-Euler step (no ``x_{n-1}`` term)."""
        return self.dt_prev is None

    def history(self, x_n, x_prev):
        """``a1 x_n + a2 x_{n-1}``: the part of the derivative known before the step."""
        _, a1, a2 = self.coefficients
        return a1 * x_n + (0.0 if self.dt_prev is None else a2 * x_prev)

    def derivative(self, x_new, x_n, x_prev):
        """``a0 x_{n+1} + a1 x_n + a2 x_{n-1}``: the time derivative at ``t_{n+1}``."""
        a0, a1, a2 = self.coefficients
        return a0 * x_new + a1 * x_n + (0.0 if self.dt_prev is None else a2 * x_prev)

    def solve(self, rate, x_n, x_prev):
        """``x_{n+1}`` whose derivative is ``rate``: ``(rate - a1 x_n - a2 x_{n-1}) / a0``."""
        a0, a1, a2 = self.coefficients
        return (rate - a1 * x_n - (0.0 if self.dt_prev is None else a2 * x_prev)) / a0


def predict(u_n: np.ndarray, du_n: np.ndarray, du_prev: np.ndarray | None, dt: float,
            dt_prev: float | None) -> np.ndarray:
    """Explicit predictor: AB2 ``u_n + dt ((1 + w/2) u'_n - (w/2) u'_{n-1})``.

    Falls back to forward Euler when no earlier derivative exists.
    """
    if du_prev is None or dt_prev is None:
        return u_n + dt * du_n
    w = dt / dt_prev
    return u_n + dt * ((1 + 0.5 * w) * du_n - 0.5 * w * du_prev)


def milne_factor(dt: float, dt_prev: float | None) -> float:
    """Factor ``Cc / (Cc + Cp)`` turning ``u_c - u_p`` into the local error.

    For the backward-Euler/forward-Euler pair of the first step it is 1/2.
    """
    if dt_prev is None:
        return 0.5
    w = dt / dt_prev
    Cc = (1 + w) ** 2 / (6 * w * (1 + 2 * w))
    Cp = 1.0 / 6.0 + 1.0 / (4.0 * w)
    return Cc / (Cc + Cp)


#: Relative rounding allowance of the end time: a step that reaches ``t_end`` to within
#: ``END_RTOL`` of the nominal step ``dt`` lands on it (:func:`step_toward`, :func:`end_time`).
END_RTOL = 1e-9


def step_toward(t: float, step: float, t_end: float, dt: float) -> float:
    """The step from ``t`` toward ``t_end``: ``step``, or the time remaining when that is
    shorter by more than rounding (``END_RTOL dt``, ``dt`` the nominal step).

    A remainder that differs from ``step`` only by the rounding of the summed steps keeps
    ``step`` itself: the same BDF2 coefficients, so the factorisation held for them is
    reused (a step shorter by 1e-16 would factorise anew for the last step).
    """
    remaining = t_end - t
    return remaining if remaining < step and abs(remaining - step) > END_RTOL * dt else step


def reached(t: float, t_end: float, dt: float) -> bool:
    """Whether the summed steps ``t`` have reached ``t_end`` (to ``END_RTOL dt``)."""
    return t >= t_end - END_RTOL * dt


def end_time(t: float, t_end: float, dt: float) -> float:
    """``t_end`` exactly when ``t`` is within rounding of it (``END_RTOL dt``), else ``t``."""
    return float(t_end) if abs(t - t_end) <= END_RTOL * dt else t


@dataclass
class StepController:
    """Accept/reject and the next step size from the local error estimate.

    Parameters
    ----------
    tol : float
        Target of the scaled local error (``err <= tol`` is accepted).
    safety : float
        Safety factor on the optimal step.
    max_ratio : float
        Largest growth ratio ``dt_new / dt``; must be < 1 + sqrt(2).
    min_ratio : float
        Smallest shrink ratio after a rejection.
    dt_min, dt_max : float
        Bounds of the step size.
    """

    tol: float = 1e-3
    safety: float = 0.9
    max_ratio: float = 2.0
    min_ratio: float = 0.2
    dt_min: float = 0.0
    dt_max: float = math.inf

    def __post_init__(self):
        positive("tol", self.tol)
        if not (1.0 < self.max_ratio < MAX_STABLE_RATIO):
            raise ValueError(f"max_ratio = {self.max_ratio}: must be in (1, 1 + sqrt(2) = "
                             f"{MAX_STABLE_RATIO:.4f}) for a zero-stable variable-step BDF2")
        if not (0.0 < self.min_ratio < 1.0):
            raise ValueError(f"min_ratio = {self.min_ratio}: must be in (0, 1)")
        positive("dt_min", self.dt_min, allow_zero=True)
        if not self.dt_max > 0:
            raise ValueError(f"dt_max = {self.dt_max!r}: must be > 0")

    def propose(self, dt: float, err: float) -> tuple[bool, float]:
        """Return ``(accepted, next dt)`` for a step of size ``dt`` with error ``err``."""
        accepted = err <= self.tol
        if err == 0.0 or not math.isfinite(err):
            factor = self.max_ratio if err == 0.0 else self.min_ratio
        else:
            factor = self.safety * (self.tol / err) ** (1.0 / 3.0)
        factor = min(self.max_ratio, max(self.min_ratio, factor))
        if not accepted:
            factor = min(factor, 0.9)
        return accepted, float(min(self.dt_max, max(self.dt_min, dt * factor)))


class StepFailedError(RuntimeError):
    """No step size was accepted by :func:`accept_step`.

    Attributes
    ----------
    reason : {"halvings", "rejections"}
        The solve kept failing, or the error control kept rejecting.
    step : float
        The last step size tried.
    error : float or None
        Its local error estimate (rejections).
    halvings, rejections : int
        Counts of this call.
    """

    def __init__(self, reason: str, step: float, error, halvings: int, rejections: int):
        super().__init__(f"step not accepted ({reason}) down to dt={step:.3g}")
        self.reason, self.step, self.error = reason, step, error
        self.halvings, self.rejections = halvings, rejections


@dataclass
class AcceptedStep:
    """What :func:`accept_step` returns: the result and how it was reached."""

    result: object
    step: float
    error: float | None
    proposal: float | None
    halvings: int
    rejections: int


def accept_step(attempt, step: float, *, failure=ArithmeticError, max_halvings: int,
                controller: StepController | None = None, estimate=None,
                max_rejections: int = 0, dt_min: float | None = None) -> AcceptedStep:
    """Try steps until one is accepted: halve on solver failure, retry on rejection.

    The one step-acceptance loop of the package (fluid-only and coupled runs).

    Parameters
    ----------
    attempt : callable
        ``attempt(step) -> result``; raises ``failure`` when its solve fails. An attempt
        changes nothing that a failed or rejected one would have to undo.
    step : float
        The first step size to try.
    failure : type or tuple of types
        Exceptions that mean "retry with half the step".
    max_halvings : int
        Halvings allowed per try; one more failure raises :class:`StepFailedError`.
    controller : StepController, optional
        Error control; without it the first converged step is accepted.
    estimate : callable
        ``estimate(result, step) -> float or None``: the scaled local error
        (``None``: no estimate, the step is accepted as it is).
    max_rejections : int
        Rejections by the error control allowed before giving up.
    dt_min : float, optional
        Smallest step (default ``controller.dt_min``, or 0 without a controller).

    Returns
    -------
    AcceptedStep

    Raises
    ------
    StepFailedError
        After ``max_halvings`` halvings of one try (or a failure at
        ``controller.dt_min``), or more than ``max_rejections`` rejections (or a
        rejection at ``dt_min``); chained to the last solver failure.
    """
    if dt_min is None:
        dt_min = 0.0 if controller is None else controller.dt_min
    halvings = rejections = 0
    while True:
        for k in range(max_halvings + 1):
            try:
                result = attempt(step)
                break
            except failure as exc:
                if k == max_halvings or step <= dt_min:
                    raise StepFailedError("halvings", step, None, halvings, rejections) from exc
                halvings += 1
                step = max(0.5 * step, dt_min)
        if controller is None:
            return AcceptedStep(result, step, None, None, halvings, rejections)
        err = estimate(result, step)
        accepted, proposal = (True, step) if err is None else controller.propose(step, err)
        if accepted:
            return AcceptedStep(result, step, err, proposal, halvings, rejections)
        rejections += 1
        if rejections > max_rejections or step <= dt_min:
            raise StepFailedError("rejections", step, err, halvings, rejections)
        step = proposal
