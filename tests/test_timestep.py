"""The shared step-acceptance loop (timestep.accept_step) and Newton loop (fluid.newton)."""

import numpy as np
import pytest

from skfem_granular import timestep as ts
from skfem_granular.fluid.errors import ConvergenceError
from skfem_granular.fluid.newton import chord_converged, newton_iterate


def test_failed_attempts_are_halved():
    tried = []

    def attempt(step):
        tried.append(step)
        if len(tried) < 3:
            raise ConvergenceError("no")
        return "ok"

    out = ts.accept_step(attempt, 0.1, failure=ConvergenceError, max_halvings=4)
    assert tried == [0.1, 0.05, 0.025] and out.step == 0.025 and out.result == "ok"
    assert out.halvings == 2 and out.error is None


def test_too_many_halvings_raise_with_the_cause():
    def attempt(step):
        raise ConvergenceError(f"no at {step}")

    with pytest.raises(ts.StepFailedError) as info:
        ts.accept_step(attempt, 1.0, failure=ConvergenceError, max_halvings=3)
    exc = info.value
    assert exc.reason == "halvings" and exc.halvings == 3 and exc.step == 0.125
    assert isinstance(exc.__cause__, ConvergenceError)


def test_rejected_steps_retry_with_the_controller_proposal():
    """Error ~ step^3: a step of 0.1 with error 8e-3 against tol 1e-3 is cut to
    0.9 (1/8)^(1/3) 0.1 = 0.045, whose error 7.3e-4 is accepted."""
    ctrl = ts.StepController(tol=1e-3)
    out = ts.accept_step(lambda step: step, 0.1, failure=ConvergenceError, max_halvings=0,
                         controller=ctrl, estimate=lambda res, step: 8.0 * step**3,
                         max_rejections=5)
    assert out.rejections == 1 and out.step == pytest.approx(0.045, rel=1e-12)
    assert out.error == pytest.approx(8 * 0.045**3, rel=1e-12) and out.error <= 1e-3
    with pytest.raises(ts.StepFailedError, match="rejections"):
        ts.accept_step(lambda step: step, 0.1, failure=ConvergenceError, max_halvings=0,
                       controller=ctrl, estimate=lambda res, step: 1.0, max_rejections=2)


def test_newton_iterate_converges_quadratically_on_sqrt2():
    """x^2 = 2 by Newton from 1: the updates square (1e-2 -> 1e-5 -> 1e-11)."""
    x = np.array([1.0])
    steps = []

    def stop(it, dx, x):
        steps.append(abs(dx[0]))
        return abs(dx[0]) < 1e-14

    it = newton_iterate(x, lambda x: x**2 - 2, lambda x, r, it: -r / (2 * x), stop,
                        max_iterations=10)
    assert x[0] == pytest.approx(np.sqrt(2), rel=1e-15) and it <= 6
    assert steps[3] < 10 * steps[2] ** 2  # quadratic contraction
    assert newton_iterate(np.array([1.0]), lambda x: x, lambda x, r, it: -0.5 * r,
                          lambda it, dx, x: False, max_iterations=3) is None


def test_chord_stop_rule_extrapolates_the_contraction():
    # rate 0.1: after an update of 1e-7 about 1.1e-8 is left, within tol 2e-8
    assert chord_converged(1e-7, 1e-6, 2, 2e-8)
    assert not chord_converged(1e-7, 1e-6, 2, 5e-9)
    assert not chord_converged(1e-7, 1.5e-7, 2, 2e-8)  # rate 0.67: no extrapolation
    assert chord_converged(1e-9, 0.0, 1, 2e-9)
