"""The unsteady DFG cylinder benchmarks (skfem_granular.validation.dfg).

The short test runs 2D-3 on the coarse mesh (64-gon, h_max 0.025: 19265 DOFs) with
dt = 0.01 to t = 2 (200 steps, about 10 s) and checks c_D, c_L and dp at t = 2 against
a finer run measured with the same code: the 128-gon mesh with h_max 0.015 (50123
DOFs) and dt = 0.0025, c_D(2) = 1.7338941, c_L(2) = -0.0084212, dp(2) = 1.2394541.
A second fine run (128-gon, h_max 0.01 to x = 1, 0.02 at the outlet, 76263 DOFs,
dt = 0.005) gave 1.7338688, -0.0083860, 1.2393833: the reference is good to 2e-5
(relative) in c_D and dp and 0.5 % in c_L, far inside the tolerances below.
The coarse run differs from it by -7.2e-4 (c_D), -3.1e-3 (c_L) and -3.3e-4 (dp),
relative; the tolerances allow about twice to three times that.

The slow test runs the full 2D-3 (t = 8) on the fine mesh with dt = 0.0025 (3200 steps,
about 260 s CPU) and checks the acceptance against John (2004): c_D,max within 0.1 %
(measured -0.019 %) and c_L,max within 1 % (measured -0.80 %).
"""

import numpy as np
import pytest

from skfem_granular.validation import dfg

#: the fine run's values at t = 2 (see the module docstring)
REF_T2 = {"cd": 1.7338941, "cl": -0.0084212, "dp": 1.2394541}
#: relative tolerances of the coarse run against them (measured: 7.2e-4, 3.1e-3, 3.3e-4)
TOL_T2 = {"cd": 1.5e-3, "cl": 1e-2, "dp": 1e-3}


@pytest.fixture(scope="module")
def coarse_2d3():
    mesh = dfg.channel_mesh(64, 0.025)
    return dfg.run_dfg("2D-3", mesh, 0.01, 2.0)


def test_2d3_short_against_fine_run(coarse_2d3):
    s = coarse_2d3
    assert s.dofs == 19265
    assert s.steps == 200 and s.rejected == 0
    assert s.t[-1] == pytest.approx(2.0, abs=1e-12)
    for key, ref in REF_T2.items():
        value = getattr(s, key)[-1]
        assert value == pytest.approx(ref, rel=TOL_T2[key]), key


def test_2d3_short_inflow_and_start(coarse_2d3):
    """Starting from rest with U(0) = 0: drag grows with the inflow, lift stays small."""
    s = coarse_2d3
    # after the first step (U = 0.0059) the drag is mostly the pressure gradient that
    # accelerates the fluid (dU/dt = 0.59): measured 0.155
    assert 0.1 < s.cd[0] < 0.2
    assert np.all(np.diff(s.cd) > 0)  # U(t) rises until t = 4
    assert np.max(np.abs(s.cl)) < 0.02


#: c_D(2.05) of the coarse run done in one go (dt = 0.01 from t = 0), measured
CD_205 = 1.78450917


def test_warm_start_same_mesh(coarse_2d3):
    """Restarted at t = 2 (the first step backward Euler, the history lost) on the same
    mesh: c_D(2.05) within 5.8e-6 of the run done in one go (1.1e-4 after the first step)."""
    r = dfg.run_dfg("2D-3", coarse_2d3.flow.mesh, 0.01, 2.05, initial=coarse_2d3.flow)
    assert r.info["t0"] == pytest.approx(2.0) and r.steps == 5
    assert r.cd[-1] == pytest.approx(CD_205, rel=2e-5)


def test_warm_start_other_polygon(coarse_2d3):
    """Interpolated to a mesh around a 96-gon (nodes just inside the 64-gon's outline):
    c_D(2.05) within 5.1e-4 of the 64-gon's run (measured; the meshes differ)."""
    r = dfg.run_dfg("2D-3", dfg.channel_mesh(96, 0.025), 0.01, 2.05, initial=coarse_2d3.flow)
    assert r.cd[-1] == pytest.approx(CD_205, rel=2e-3)


def test_peak_parabola():
    t = np.linspace(0.0, 1.0, 11)
    y = 2.0 - 3.0 * (t - 0.537) ** 2
    value, at = dfg.peak(t, y)
    assert value == pytest.approx(2.0, abs=1e-12)
    assert at == pytest.approx(0.537, abs=1e-12)
    assert dfg.peak([0.0, 1.0], [1.0, 0.5]) == (1.0, 0.0)  # maximum at the end


def test_lift_period_sine():
    t = np.arange(0.0, 5.0, 0.004)
    period, n = dfg.lift_period(t, 0.3 + np.sin(2 * np.pi * t / 0.33), 1.0)
    assert period == pytest.approx(0.33, rel=1e-4)
    assert n == 11
    with pytest.raises(ValueError, match="t_from"):
        dfg.lift_period(t, np.sin(2 * np.pi * t / 0.33), 4.9)


def test_inflow_speed():
    u3 = dfg.inflow_speed("2D-3")
    assert u3(0.0) == 0.0 and u3(4.0) == pytest.approx(1.5)
    u2 = dfg.inflow_speed("2D-2", ramp=1.0)
    assert u2(0.0) == 0.0 and u2(0.5) == pytest.approx(0.75) and u2(3.0) == 1.5
    assert dfg.inflow_speed("2D-2", ramp=0.0)(0.0) == 1.5


@pytest.mark.parametrize("call, field", [
    (lambda: dfg.channel_mesh(63), "sides"),
    (lambda: dfg.channel_mesh(8), "sides"),
    (lambda: dfg.channel_mesh(64, 0.0), "h_max"),
    (lambda: dfg.channel_mesh(64, 0.02, h_outlet=0.01), "h_outlet"),
    (lambda: dfg.channel_mesh(64, 0.02, wake_end=0.1), "wake_end"),
    (lambda: dfg.inflow_speed("2D-1"), "case"),
    (lambda: dfg.inflow_speed("2D-2", ramp=-1.0), "ramp"),
    (lambda: dfg.run_dfg("2D-3", None, 0.0), "dt"),
    (lambda: dfg.run_dfg("2D-3", None, 0.01, 9.0), "t_end"),
    (lambda: dfg.run_dfg("2D-2", None, 0.01, 5.0, tol=1.0), "tol"),
    (lambda: dfg.run_dfg("2D-2", None, 0.01, 5.0, initial="flow"), "initial"),
])
def test_bad_input(call, field):
    with pytest.raises(ValueError, match=f"^{field} = "):
        call()


def test_summary_wrong_case(coarse_2d3):
    with pytest.raises(ValueError, match="series.case"):
        dfg.dfg2d2_summary(coarse_2d3)


@pytest.mark.slow
def test_2d3_full_acceptance():
    s = dfg.run_dfg("2D-3", dfg.channel_mesh(128, 0.015), 0.0025)
    out = dfg.dfg2d3_summary(s)
    assert abs(out["err_cd_max"]) < 1e-3
    assert abs(out["err_cl_max"]) < 1e-2
    assert abs(out["err_t_cd_max"]) < 0.01 and abs(out["err_t_cl_max"]) < 0.02
    assert abs(out["err_dp_end"]) < 0.01
