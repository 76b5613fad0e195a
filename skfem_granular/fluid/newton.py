"""The Newton / chord iteration every nonlinear solve of the package runs.

``x`` is updated in place: each iteration evaluates the residual, asks for a
correction and adds it, then asks whether to stop. What differs between the
callers is only what they pass in:

- :func:`~skfem_granular.fluid.solve_steady`: a fresh Jacobian per iteration
  (Newton), stopping on the relative residual or update;
- :class:`~skfem_granular.fluid.unsteady.BDF2Integrator`: the factorised
  BDF2-Stokes operator (chord), switching to GMRES on the exact Jacobian when
  the contraction is slow;
- the couplings of :mod:`skfem_granular.coupled`: the chord iteration on the
  coupled fluid + rigid-body system, stopping on the update with an estimate
  of the error left from the contraction rate (:func:`chord_converged`).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np


def newton_iterate(x: np.ndarray, residual: Callable, correction: Callable, stop: Callable, *,
                   max_iterations: int, index=slice(None)) -> int | None:
    """Iterate ``x[index] += correction(x, residual(x), it)`` until ``stop`` says so.

    Parameters
    ----------
    x : ndarray
        The iterate, updated in place.
    residual : callable
        ``residual(x)``: whatever ``correction`` needs (a vector, or a tuple).
    correction : callable
        ``correction(x, r, it) -> dx`` for the entries ``x[index]``.
    stop : callable
        ``stop(it, dx, x) -> bool``, called after each update; it may raise
        (a NaN, a diverging iteration).
    max_iterations : int
        Iteration limit.
    index : slice or ndarray
        The entries of ``x`` that are unknowns (default: all).

    Returns
    -------
    int or None
        The number of iterations taken, ``None`` when ``stop`` never said so
        within ``max_iterations`` (the caller raises with its own message).
    """
    for it in range(1, max_iterations + 1):
        r = residual(x)
        dx = correction(x, r, it)
        x[index] += dx
        if stop(it, dx, x):
            return it
    return None


def chord_converged(dn: float, prev: float, it: int, tol: float) -> bool:
    """Whether a linearly contracting iteration has reached ``tol``.

    ``dn`` is the size of this update, ``prev`` of the one before. A chord
    iteration contracts at about ``rate = dn / prev``; the error left after
    this update is about ``dn * rate / (1 - rate)``, so it stops as soon as
    either that or ``dn`` itself is within ``tol``.
    """
    rate = dn / prev if it > 1 and prev > 0 else 1.0
    return dn <= tol or (rate < 0.5 and dn * rate / (1.0 - rate) <= tol)


def chord_stalled(dn: float, prev: float | None, tol: float, patience: float = 3.0) -> bool:
    """Whether a chord iteration is too slow to go on: it diverges, or, at its current
    contraction rate ``dn / prev``, it would need more than ``patience`` further
    iterations to bring the update ``dn`` down to ``tol``.

    The fluid's BDF2 integrator then goes on with GMRES on the exact Jacobian
    preconditioned by the same factorisation. (The monolithic coupling refreshes its
    Jacobian on a simpler rate test, measured faster there:
    :data:`~skfem_granular.coupled.monolithic.REFRESH_RATE`.)
    """
    if prev is None or prev <= 0.0 or dn <= tol:
        return False
    rate = dn / prev
    if rate >= 1.0:
        return True
    return math.log(tol / dn) / math.log(max(rate, 1e-300)) > patience
