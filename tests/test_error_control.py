"""The adaptive step's error estimate against the true local error.

The step controller accepts a step when Milne's estimate (AB2 predictor against the
BDF2 corrector) is below the tolerance; that is only worth something if the estimate
tracks the error the step really makes. Here the true local error is measured on the
Taylor-Green flow (unsteady Stokes, exact boundary data): a step taken from the exact
history of the space-discrete problem (states and derivatives at ``t_{n-1}``, ``t_n`` of
a reference run with a 100x smaller step) is compared with that reference at
``t_{n+1}``.
"""

import numpy as np
import pytest
from helpers import box

import skfem_granular as sg

NU = 1.0
T = 0.4           # the step starts here (the fastest transients of the start have decayed)
H_REF = 2.5e-4    # reference step: its own error is below 1e-1 of the smallest local error
STEPS = (0.05, 0.025, 0.0125)


def taylor_green(x, y, t):
    d = np.exp(-2 * NU * t)
    return -np.cos(x) * np.sin(y) * d, np.sin(x) * np.cos(y) * d


def _integrator(space):
    bc = {k: taylor_green for k in ("left", "right", "bottom", "top")}
    return sg.BDF2Integrator(space, sg.Fluid(1.0, NU), bc, convection=False,
                             u0=lambda x, y: taylor_green(x, y, 0.0), newton_tol=1e-13,
                             velocity_scale=1.0)


@pytest.fixture(scope="module")
def local_errors():
    """``(estimate, true error)`` of one step of each size in :data:`STEPS` (w = 1)."""
    space = sg.TaylorHood(box(0.0, 0.0, np.pi, np.pi, 0.2))
    nu = space.nu
    ref = _integrator(space)
    states = [(ref.x.copy(), ref.du.copy())]
    for _ in range(round((T + max(STEPS)) / H_REF)):
        x, *_ = ref.try_step(H_REF)
        ref.commit(x, H_REF)
        states.append((ref.x.copy(), ref.du.copy()))
    out = []
    n = round(T / H_REF)
    for dt in STEPS:
        k = round(dt / H_REF)
        step = _integrator(space)  # the step's history: the reference's, exact
        step.t, step.dt_prev = n * H_REF, k * H_REF
        step.x, step.du = states[n][0].copy(), states[n][1].copy()
        step.u_prev, step.du_prev = states[n - k][0][:nu].copy(), states[n - k][1].copy()
        x, _, estimate, _ = step.try_step(k * H_REF)
        u = x[:nu]
        true = np.abs(u - states[n + k][0][:nu]).max() / max(np.abs(u).max(), 1.0)
        out.append((estimate, true))
    return np.array(out)


def test_estimate_is_third_order_like_the_local_error(local_errors):
    """Halving the step divides the estimate by 2^3 (the local error of BDF2 is
    O(dt^3)); the true error follows with an order approaching 3 (the space-discrete
    flow's faster modes, which the largest steps do not resolve, make it lower there)."""
    est, true = local_errors.T
    est_orders = np.log2(est[:-1] / est[1:])
    true_orders = np.log2(true[:-1] / true[1:])
    assert est_orders == pytest.approx([3.0, 3.0], abs=0.15), est_orders
    assert 2.3 < true_orders[0] < true_orders[1] < 3.1, true_orders


def test_estimate_bounds_the_true_error_and_converges_to_it(local_errors):
    """Measured (mesh 0.2, steps 0.05 / 0.025 / 0.0125): the estimate is 2.8, 2.1 and
    1.7 times the true local error. It never underestimates (a step accepted at the
    tolerance has made at most that error), and the ratio falls towards 1 as the step
    resolves the flow: Milne's device is asymptotically exact."""
    est, true = local_errors.T
    ratio = est / true
    assert np.all(ratio >= 1.0), ratio
    assert np.all(np.diff(ratio) < 0.0), ratio
    assert ratio[-1] < 2.0 and ratio[0] < 4.0, ratio
