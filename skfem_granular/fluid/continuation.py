"""Continuation in the viscosity for steady Navier-Stokes solves that Newton cannot start.

Newton's method converges from a good enough initial guess only; for a steady
flow at a high Reynolds number the Stokes solution is not one. The remedy is a
homotopy: solve at a larger viscosity ``f eta`` (the Reynolds number divided by
``f``), where Newton converges from rest, and lower ``f`` towards 1 in steps,
each solve starting from the last two converged flows extrapolated in the
Reynolds number (a secant predictor). The step shrinks when a solve
fails and grows again when one converges quickly, so the path costs a few
Newton iterations per stage. The boundary data, body force and mesh stay those
of the problem, so the end point is the requested solution (the same Newton
tolerance applies to it).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol, TypeVar

import numpy as np

from .errors import ConvergenceError
from .flow import SolveReport
from .properties import Fluid

#: Viscosity factors tried first, in order, until a Newton solve from rest converges.
START_FACTORS = (4.0, 16.0, 64.0, 256.0, 1024.0)

#: First ratio between successive viscosity factors on the way down.
FIRST_RATIO = 0.25

#: The largest step down: a stage that converged in at most :data:`QUICK` iterations
#: squares the ratio, down to this.
SMALLEST_RATIO = 1.0 / 16.0

#: Newton iterations of a stage that count as quick.
QUICK = 4

#: Give up when a failed stage would make the ratio larger than this (no progress).
LARGEST_RATIO = 0.98


class _Solution(Protocol):
    """What the continuation reads of a solve's result (a :class:`~.flow.Flow`)."""

    x: np.ndarray
    report: SolveReport


_S = TypeVar("_S", bound=_Solution)


def viscosity_continuation(solve: Callable[[Fluid, _S | np.ndarray | None], _S], fluid: Fluid
                           ) -> tuple[_S, list[dict]]:
    """Reach the steady flow at ``fluid``'s viscosity through larger viscosities.

    Parameters
    ----------
    solve : callable
        ``solve(fluid, initial) -> Flow``: one Newton solve of the problem with the
        given fluid properties, started from the flow ``initial`` (``None``: from rest),
        raising :class:`~skfem_granular.fluid.errors.ConvergenceError` when it fails.
    fluid : Fluid
        The fluid of the problem to solve.

    Returns
    -------
    flow, stages
        The flow at ``fluid`` (from the last ``solve``) and the path: one dict per
        attempted stage, ``factor`` (viscosity multiplier), ``iterations``,
        ``converged``.

    Raises
    ------
    ConvergenceError
        When no start factor converges, or the steps down stall.
    """
    stages = []

    def attempt(factor, initial):
        try:
            flow = solve(Fluid(fluid.density, fluid.viscosity * factor), initial)
        except ConvergenceError:
            stages.append(dict(factor=factor, iterations=None, converged=False))
            return None
        stages.append(dict(factor=factor, iterations=flow.report.iterations, converged=True))
        return flow

    flow = None
    for factor in START_FACTORS:
        flow = attempt(factor, None)
        if flow is not None:
            break
    if flow is None:
        raise ConvergenceError(
            f"solve_steady: Newton did not converge even at {START_FACTORS[-1]:g} times the "
            f"viscosity {fluid.viscosity:g} (continuation start); check the boundary data")
    ratio = FIRST_RATIO
    previous = None  # the converged stage before ``flow``: (factor, flow)
    while factor > 1.0:
        target = factor * ratio
        if target < 1.0 + 1e-9:
            target = 1.0
        found = attempt(target, _secant_guess(previous, (factor, flow), target))
        if found is None:
            ratio = ratio**0.5
            if ratio > LARGEST_RATIO:
                raise ConvergenceError(
                    f"solve_steady: continuation stalled at {factor:.4g} times the viscosity "
                    f"(Reynolds number {factor:.4g} times too small): no steady solution was "
                    f"reached on this path; the flow may be unsteady there, or the mesh too "
                    f"coarse for it")
            continue
        previous, flow, factor = (factor, flow), found, target
        if found.report.iterations <= QUICK:
            ratio = max(ratio * ratio, SMALLEST_RATIO)
    return flow, stages


def _secant_guess(previous, current, target):
    """Initial guess at viscosity factor ``target``: the last two converged flows
    extrapolated linearly in the Reynolds number (``1 / factor``), or the last one."""
    f1, flow1 = current
    if previous is None:
        return flow1
    f0, flow0 = previous
    w = (1.0 / target - 1.0 / f1) / (1.0 / f1 - 1.0 / f0)
    return flow1.x + w * (flow1.x - flow0.x)
