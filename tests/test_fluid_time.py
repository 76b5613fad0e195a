"""BDF2 time integration: coefficients, Taylor-Green temporal orders (validation case 6)."""

import math

import numpy as np
import pytest
from helpers import box

import skfem_granular as sg
from skfem_granular import timestep as ts

NU = 0.1


def taylor_green(x, y, t):
    """u = -cos x sin y e^{-2 nu t}, v = sin x cos y e^{-2 nu t} (rho = 1)."""
    d = np.exp(-2 * NU * t)
    return -np.cos(x) * np.sin(y) * d, np.sin(x) * np.cos(y) * d


@pytest.mark.parametrize("w", [1.0, 0.5, 1.7])
def test_bdf2_coefficients_exact_for_quadratics(w):
    """The variable-step formula differentiates t^2 exactly at t_{n+1}."""
    dt = 0.3
    a0, a1, a2 = ts.bdf2_coefficients(dt, dt / w)
    t1, t0, tm = 1.0, 1.0 - dt, 1.0 - dt - dt / w
    for f, df in ((lambda t: 1.0, 0.0), (lambda t: t, 1.0), (lambda t: t * t, 2 * t1)):
        assert a0 * f(t1) + a1 * f(t0) + a2 * f(tm) == pytest.approx(df, abs=1e-12)
    if w == 1.0:
        assert (a0 * dt, a1 * dt, a2 * dt) == pytest.approx((1.5, -2.0, 0.5))


def test_milne_factor_constant_step():
    assert ts.milne_factor(1.0, 1.0) == pytest.approx(8 / 23)


def test_step_controller_caps_growth_below_zero_stability_limit():
    with pytest.raises(ValueError, match="max_ratio"):
        ts.StepController(max_ratio=2.5)
    c = ts.StepController(tol=1e-3, max_ratio=2.0)
    assert c.propose(1.0, 0.0) == (True, 2.0)
    ok, dt = c.propose(1.0, 8e-3)  # error 8x too large: reject, shrink by ~1/2
    assert not ok and dt == pytest.approx(0.9 * 0.5)


@pytest.fixture(scope="module")
def tg_space():
    return sg.TaylorHood(box(0.0, 0.0, np.pi, np.pi, 0.05))


def _run(space, steps, scheme="bdf2", convection=True):
    bc = {k: taylor_green for k in ("left", "right", "bottom", "top")}
    integ = sg.BDF2Integrator(
        space,
        sg.Fluid(1.0, NU),
        bc,
        convection=convection,
        u0=lambda x, y: taylor_green(x, y, 0.0),
        scheme=scheme,
        newton_tol=1e-12,
    )
    for dt in steps:
        x, *_ = integ.try_step(dt)
        integ.commit(x, dt)
    return integ


def _orders(space, pattern, scheme, levels, convection=True, T=1.0):
    """Temporal self-convergence on a fixed mesh (the spatial error cancels).

    Each level repeats ``pattern`` (relative step sizes) k times over [0, T];
    orders come from differences of consecutive levels.
    """
    sols = []
    for k in levels:
        base = np.repeat(np.asarray(pattern, dtype=float), k)
        sols.append(_run(space, base * T / base.sum(), scheme, convection).x[: space.nu])
    d = np.array([np.abs(a - b).max() for a, b in zip(sols[:-1], sols[1:], strict=True)])
    return np.log2(d[:-1] / d[1:]), d


def test_bdf2_order_two_constant_steps_navier_stokes(tg_space):
    orders, d = _orders(tg_space, [1.0] * 4, "bdf2", (2, 4, 8, 16))
    assert np.all(np.abs(orders - 2.0) < 0.2), (orders, d)


def test_bdf2_order_two_variable_steps(tg_space):
    """Step ratios w alternate between 2 and 1/2 (w != 1 on every step).

    Taylor-Green is also an exact solution of the unsteady Stokes equations
    (its convection term is a gradient), which keeps this test cheap.
    """
    orders, d = _orders(
        tg_space, [1.0, 2.0, 1.0, 2.0], "bdf2", (4, 8, 16, 32, 64), convection=False
    )
    assert np.all(np.abs(orders[-2:] - 2.0) < 0.2), (orders, d)


def test_backward_euler_order_one(tg_space):
    orders, d = _orders(tg_space, [1.0] * 4, "euler", (2, 4, 8, 16))
    assert np.all(np.abs(orders - 1.0) < 0.2), (orders, d)


def test_evolve_matches_exact_solution_and_yields_steps(tg_space):
    bc = {k: taylor_green for k in ("left", "right", "bottom", "top")}
    ts_, infos = [], []
    for t, flow in sg.evolve(
        tg_space, sg.Fluid(1.0, NU), bc, dt=0.05, t_end=0.5, u0=lambda x, y: taylor_green(x, y, 0.0)
    ):
        ts_.append(t)
        infos.append(flow.step)
    assert ts_[-1] == 0.5 and len(ts_) == 10
    assert all(i.rejected == 0 for i in infos)
    loc = tg_space.velocity_doflocs
    ux, uy = taylor_green(loc[0], loc[1], 0.5)
    exact = np.where(tg_space.component == 0, ux, uy)
    assert np.abs(flow.u - exact).max() < 2e-3
    # pressure: p = -(cos 2x + cos 2y)/4 e^{-4 nu t}, up to a constant
    pts = np.array([[0.5, 1.5, 2.5], [1.0, 2.0, 0.7]])
    p = flow.pressure(pts)
    pe = -(np.cos(2 * pts[0]) + np.cos(2 * pts[1])) / 4 * math.exp(-4 * NU * 0.5)
    assert np.ptp(p - pe) < 2e-3


def test_adaptive_steps_keep_error_below_tolerance(tg_space):
    bc = {k: taylor_green for k in ("left", "right", "bottom", "top")}
    tol = 1e-5
    steps = [
        flow.step
        for _, flow in sg.evolve(
            tg_space,
            sg.Fluid(1.0, NU),
            bc,
            dt=1e-3,
            t_end=1.0,
            adaptive=True,
            tol=tol,
            u0=lambda x, y: taylor_green(x, y, 0.0),
            velocity_scale=1.0,
        )
    ]
    errs = [s.error for s in steps if s.error is not None]
    assert max(errs) <= tol
    dts = np.array([s.dt for s in steps])
    assert np.all(dts[1:] / dts[:-1] <= 2.0 + 1e-12)
    assert dts.max() > 20 * dts[0]  # the controller grows the step from the small start


def test_unsteady_stokes_is_one_solve_per_step(tg_space):
    integ = _run(tg_space, [0.1] * 5, convection=False)
    assert integ.solver.stats.factorizations == 2  # backward Euler start, then BDF2
    assert integ.solver.stats.solves == 5


def test_bad_time_arguments():
    space = sg.TaylorHood(box(0, 0, 1, 1, 0.1))
    with pytest.raises(ValueError, match="dt"):
        next(sg.evolve(space, sg.Fluid(), {"left": (0, 0)}, dt=-1.0, t_end=1.0))
    with pytest.raises(ValueError, match="t_end"):
        next(sg.evolve(space, sg.Fluid(), {"left": (0, 0)}, dt=0.1, t_end=-1.0))


def test_flow_starting_from_rest_with_growing_boundary_data():
    """Zero boundary data at t0 (a lid that starts moving) must not break the Newton test."""
    space = sg.TaylorHood(box(0.0, 0.0, 1.0, 1.0, 0.02))
    bc = {"top": lambda x, y, t: (t + 0 * x, 0 * x), "left": (0, 0), "right": (0, 0),
          "bottom": (0, 0)}
    steps = [f.step for _, f in sg.evolve(space, sg.Fluid(1.0, 0.01), bc, dt=0.1, t_end=0.5)]
    assert len(steps) == 5 and all(s.iterations < 10 for s in steps)
