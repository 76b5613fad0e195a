"""The Newton / chord iteration every nonlinear solve of the package runs.

``x`` is updated in place: each iteration evaluates the residual, asks for a
correction and adds it, then asks whether to stop. What differs between the
callers is only what they pass in:

- :func:`~skfem_granular.fluid.solve_steady`: a fresh Jacobian per iteration
  (Newton), stopping on the relative residual or update;
- :class:`~skfem_granular.fluid.unsteady.BDF2Integrator`: the factorised
  BDF2-Stokes operator (chord), stopping on the update;
- the couplings of :mod:`skfem_granular.coupled`: the chord iteration on the
  coupled fluid + rigid-body system, stopping on the update with an estimate
  of the error left from the contraction rate (:func:`chord_converged`).

Both chord iterations share one stall policy (:class:`ChordStall`): when the
iterations a held factorisation has cost beyond a fresh Jacobian's add up to
the price of a refresh, or the contraction would not reach the tolerance
within the iteration limit, the Newton Jacobian at the iterate is factorised
and the iteration goes on with it.
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


#: The rate rule (``STALL_RULE = "rate"``): a chord iteration has stalled when an update
#: is more than this fraction of the one before. Measured against the rule "more than
#: three further iterations at the current contraction rate" and against GMRES on the
#: exact Jacobian in place of a refresh: docs/benchmarks.md, "One stall policy".
STALL_RATE = 0.3

#: ``"amortised"`` (default): a refresh when the iterations the held factorisation has
#: cost beyond a fresh Jacobian's, summed over the steps that used it, reach
#: :data:`REFRESH_ITERATIONS`; ``"rate"``: a refresh whenever an update is more than
#: :data:`STALL_RATE` of the one before (the rule up to this version, kept for
#: comparisons). Either refreshes when the iteration would not reach its tolerance within
#: the iteration limit, or does not contract.
STALL_RULE = "amortised"

#: Iterations a step takes on a fresh Newton Jacobian (two updates and the one that
#: confirms): the ones beyond are what the held operator costs.
FRESH_ITERATIONS = 3

#: What a refresh (assembling and factorising the Newton Jacobian) costs in chord
#: iterations (a residual and a back-substitution each): measured 27-41 on the immersed
#: collapse columns of 25 to 400 grains (42k to 600k unknowns, SuperLU), almost
#: independent of the size (docs/benchmarks.md, "One stall policy").
REFRESH_ITERATIONS = 30.0


class ChordStall:
    """When a chord iteration has stalled, and when to refresh its operator.

    The one rule of every chord iteration of the package, the fluid's
    :class:`~skfem_granular.fluid.unsteady.BDF2Integrator` and the
    :class:`~skfem_granular.coupled.monolithic.MonolithicCoupling`. A chord
    iteration runs on a held factorisation (the BDF2-Stokes matrix, or an earlier
    Newton Jacobian) that drifts from the step's Jacobian as the flow and the mesh
    move; each step it is kept costs iterations that a fresh Jacobian would not
    take. The default rule (:data:`STALL_RULE` ``"amortised"``) pays for a refresh
    when those extra iterations, counted on the ``ledger`` of the factorisation
    (:class:`~skfem_granular.fluid.factor_cache.FactorCache`:
    ``extra_iterations``, the iterations of each step beyond
    :data:`FRESH_ITERATIONS`, summed over the steps since it was made), reach the
    price of a refresh, :data:`REFRESH_ITERATIONS`: the rent-or-buy rule, never
    more than twice the cost of the best choice made in hindsight. A refresh is
    also due when at the current contraction rate the updates would not come down
    to the tolerance within the iterations left, or do not contract. The caller
    then factorises the Newton Jacobian at the iterate before the next correction
    and goes on with it
    (:meth:`~skfem_granular.fluid.factor_cache.FactorCache.factorize_system`), and
    later steps with the same ``a0`` keep it as their chord operator. The rate is
    judged on two updates made with the same operator: from the second iteration
    after a refresh on.

    Parameters
    ----------
    max_iterations : int
        The iteration limit of the step.
    ledger : FactorCache, optional
        Where the extra iterations of the held factorisation are counted (its
        ``extra_iterations``, reset by every factorisation); without it (or with
        :data:`STALL_RULE` ``"rate"``) a refresh is due whenever an update is more
        than :data:`STALL_RATE` of the one before.

    Examples
    --------
    One object per step:

    >>> stall = ChordStall(max_iterations=12, ledger=factors)  # doctest: +SKIP
    >>> stall.observe(it, dn, done, tol)       # after each update
    >>> if stall.refresh_due(it): ...          # before each correction: factorise

    Attributes
    ----------
    prev : float or None
        The size of the last update.
    refreshes : int
        Refreshes asked for in this step.
    reason : str or None
        Why the last refresh was asked for: ``"ledger_at_start"`` (the held
        factorisation's extra iterations had reached :data:`REFRESH_ITERATIONS` in
        earlier steps), ``"ledger"`` (they reach it in this step), ``"rate"`` (the rate
        rule), ``"diverging"`` (an update not smaller than the one before) or
        ``"limit"`` (the tolerance not reached within the iteration limit at this rate).
    """

    def __init__(self, max_iterations: int, ledger=None) -> None:
        self.rate = STALL_RATE
        self.max_iterations = int(max_iterations)
        self.prev: float | None = None
        self.refreshes = 0
        self.ledger = ledger if STALL_RULE == "amortised" else None
        self._due = self.ledger is not None and self.ledger.extra_iterations >= REFRESH_ITERATIONS
        self.reason: str | None = "ledger_at_start" if self._due else None
        self._since = 0  # iteration of the last refresh (0: the operator the step began with)

    def _extra(self, it: int) -> int:
        """Iterations of this step on the held operator beyond a fresh one's."""
        return max(0, it - self._since - FRESH_ITERATIONS)

    def observe(self, it: int, dn: float, done: bool, tol: float) -> None:
        """Record update ``it`` of size ``dn`` (``done``: the iteration stops here; ``tol``:
        the size of update it stops at)."""
        prev, self.prev = self.prev, dn
        if done and self.ledger is not None:
            self.ledger.extra_iterations += self._extra(it)
        if done or prev is None or it < self._since + 2 or prev <= 0.0:
            return
        rate = dn / prev
        reason: str | None
        if rate >= 1.0:
            reason = "diverging"
        elif self.ledger is not None:
            over = self.ledger.extra_iterations + self._extra(it) >= REFRESH_ITERATIONS
            reason = "ledger" if over else None
        else:
            reason = "rate" if rate > self.rate else None
        # too slow, or (iterations still needed at this rate) too many for the limit
        if reason is None and (dn > tol and rate > 0.0 and math.log(tol / dn) / math.log(rate)
                               > self.max_iterations - it):
            reason = "limit"
        if reason is not None:
            self._due, self.reason = True, reason

    def refresh_due(self, it: int) -> bool:
        """Whether to factorise the Jacobian before correction ``it`` (counted if so)."""
        if not self._due:
            return False
        self._due, self._since = False, it
        self.refreshes += 1
        return True
