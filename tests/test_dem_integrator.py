"""BDF2 predictor-corrector: coefficients and observed order (dem.integrator)."""

import numpy as np
import pytest

from skfem_granular.dem import BDF2History, bdf2_coefficients
from skfem_granular.dem.integrator import correct, predict

OMEGA, ZETA = 2.0, 0.1


def exact(t):
    """x'' + 2 zeta omega x' + omega^2 x = 0, x(0) = 1, x'(0) = 0."""
    wd = OMEGA * np.sqrt(1 - ZETA**2)
    return np.exp(-ZETA * OMEGA * t) * (np.cos(wd * t) + ZETA * OMEGA / wd * np.sin(wd * t))


def integrate(steps):
    """Integrate the damped oscillator in all three rows of a (3, 2) state."""
    q = np.ones((3, 2))
    v = np.zeros((3, 2))

    def acc(q, v):
        return -(OMEGA**2) * q - 2 * ZETA * OMEGA * v

    h = BDF2History()
    h.a = acc(q, v)
    t = 0.0
    for dt in steps:
        qp, vp = predict(q, v, h, dt)
        q, v = correct(q, v, h, acc(qp, vp), dt)
        t += dt
    return t, q


def test_coefficients_constant_step():
    a0, a1, a2 = bdf2_coefficients(0.1, 0.1)
    np.testing.assert_allclose([a0, a1, a2], [1.5 / 0.1, -2.0 / 0.1, 0.5 / 0.1], rtol=1e-14)


@pytest.mark.parametrize("w", [0.5, 1.7])
def test_coefficients_exact_for_quadratics(w):
    # the variable-step BDF2 derivative is exact for y = t^2 (second order)
    dt = 0.3
    dtp = dt / w
    a0, a1, a2 = bdf2_coefficients(dt, dtp)
    t1, t0, tm = 1.0 + dt, 1.0, 1.0 - dtp
    assert a0 * t1**2 + a1 * t0**2 + a2 * tm**2 == pytest.approx(2 * t1, rel=1e-12)
    assert a0 + a1 + a2 == pytest.approx(0.0, abs=1e-12)


def test_observed_order_two_constant_steps():
    T = 5.0
    errors = []
    for n in (400, 800, 1600, 3200):
        t, q = integrate(np.full(n, T / n))
        errors.append(np.abs(q - exact(t)).max())
    orders = np.log2(np.array(errors[:-1]) / errors[1:])
    assert np.all(np.abs(orders - 2.0) < 0.05), orders


def test_observed_order_two_variable_steps():
    # alternating step ratios w = 1.5 and 1/1.5 (below the 1 + sqrt(2) zero-stability bound)
    T = 5.0
    errors = []
    for n in (200, 400, 800, 1600):
        pattern = np.tile([1.0, 1.5], n)
        steps = pattern / pattern.sum() * T
        t, q = integrate(steps)
        errors.append(np.abs(q - exact(t)).max())
    orders = np.log2(np.array(errors[:-1]) / errors[1:])
    assert np.all(np.abs(orders - 2.0) < 0.05), orders


def test_free_flight_is_exact():
    # constant acceleration: the scheme reproduces x = x0 + v0 t + g t^2 / 2 to round-off
    q, v = np.zeros((3, 1)), np.array([[1.0], [2.0], [3.0]])
    g = np.array([[0.0], [-9.81], [0.0]])
    h = BDF2History()
    h.a = g
    dt, n = 1e-3, 500
    for _ in range(n):
        qp, vp = predict(q, v, h, dt)
        q, v = correct(q, v, h, g, dt)
    T = dt * n
    np.testing.assert_allclose(q[:, 0], [1.0 * T, 2.0 * T - 0.5 * 9.81 * T**2, 3.0 * T],
                               rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(v[:, 0], [1.0, 2.0 - 9.81 * T, 3.0], rtol=1e-12)


def test_system_restarts_history_on_large_step_growth():
    # growing the step by more than MAX_STEP_RATIO restarts the BDF2 history;
    # free fall stays exact either way (both starts are exact for constant acceleration)
    from skfem_granular.dem import DEMSystem, Particle, Polygon
    from skfem_granular.dem.system import MAX_STEP_RATIO

    s = DEMSystem([Particle(Polygon.regular(6, 1e-3), 2650.0)])
    s.step(s.dt_stable / 10)
    s.step(s.dt_stable / 10)
    assert s.bdf2.dt_prev is not None
    s.step(s.dt_stable)  # ratio 10 > MAX_STEP_RATIO
    assert MAX_STEP_RATIO < 1 + np.sqrt(2)
    assert s.bdf2.q_prev is not None and s.bdf2.dt_prev == s.dt_stable
    T = s.t
    assert s.velocities[1, 0] == pytest.approx(-9.81 * T, rel=1e-12)
    assert s.positions[1, 0] == pytest.approx(-0.5 * 9.81 * T**2, rel=1e-10)
