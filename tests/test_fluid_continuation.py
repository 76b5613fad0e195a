"""Steady Navier-Stokes at Reynolds numbers where Newton from the Stokes flow fails:
the viscosity continuation of ``solve_steady`` (module ``fluid.continuation``)."""

from types import SimpleNamespace

import numpy as np
import pytest

from skfem_granular.fluid import ConvergenceError, Fluid, TaylorHood, solve_steady
from skfem_granular.fluid.continuation import viscosity_continuation
from skfem_granular.validation.terminal import FrameProblem, frame_mesh


def _fake_solver(reach):
    """A 'Newton solve' that converges when started from rest at a viscosity factor of at
    least 8, or from a flow whose factor is within ``reach`` of the new one; the 'flow'
    records the factor it was solved at."""
    calls = []

    def solve(fluid, initial):
        f = fluid.viscosity
        calls.append(f)
        if initial is None:
            ok = f >= 8.0
        else:
            f0 = initial.x[0] if hasattr(initial, "x") else initial[0]
            ok = f / f0 >= reach
        if not ok:
            raise ConvergenceError("fake")
        return SimpleNamespace(x=np.array([f]), report=SimpleNamespace(iterations=5))

    return solve, calls


def test_continuation_walks_down_to_the_requested_viscosity_exactly():
    solve, calls = _fake_solver(reach=0.3)
    flow, stages = viscosity_continuation(solve, Fluid(1.0, 1.0))
    assert calls[-1] == 1.0 and flow.x[0] == 1.0  # ends at the requested fluid, not near it
    assert [s["factor"] for s in stages[:2]] == [4.0, 16.0]  # 4 fails from rest, 16 starts
    assert stages[1]["converged"] and not stages[0]["converged"]
    done = [s["factor"] for s in stages if s["converged"]]
    assert all(b < a for a, b in zip(done, done[1:], strict=False))  # always downwards
    ratios = [b / a for a, b in zip(done, done[1:], strict=False)]
    assert min(ratios) >= 0.3  # no converged step beyond the solver's reach


def test_continuation_reports_a_stall_in_one_line():
    solve, _ = _fake_solver(reach=0.99)
    with pytest.raises(ConvergenceError, match="continuation stalled at 16 times the viscosity"):
        viscosity_continuation(solve, Fluid(1.0, 1.0))


def test_solve_steady_rejects_an_unknown_continuation():
    with pytest.raises(ValueError, match="continuation = 'yes': must be 'auto' or 'off'"):
        solve_steady(None, Fluid(1.0, 1.0), {}, True, continuation="yes")


@pytest.fixture(scope="module")
def frame():
    """A 2.5 mm 32-gon held in a 2 cm channel, walls and inflow at U past it (the
    particle frame of a settling disk, validation.terminal), coarse: 509 vertices."""
    pb = FrameProblem(width=0.02, radius=1.25e-3, sides=32, rho_p=1500.0, rho_f=1000.0,
                      mu=1e-3, g=9.81, upstream=0.03, downstream=0.06, delta_l=0.5e-3)
    return TaylorHood(frame_mesh(pb).mesh), pb.fluid


def _bc(Re):
    U = Re * 1e-6 / 2.5e-3  # rho_f U d / mu with d = 2.5 mm, nu = 1e-6
    return {"left": (0.0, U), "right": (0.0, U), "bottom": (0.0, U), "particle0": (0.0, 0.0)}


def test_steady_flow_past_a_disk_at_re_200_is_reached_by_continuation(frame):
    """Newton from the Stokes flow fails at Re = 200 (measured: diverges); with the
    continuation it converges (measured path: 4, 2, sqrt 2, 1 times the viscosity, two
    failed steps). The solution does not depend on the path: reached instead by raising
    the inflow from Re = 100 (plain Newton from that flow), the drag agrees to 1e-9 and
    Newton started from the continued flow stops at once."""
    space, fluid = frame
    with pytest.raises(ConvergenceError):
        solve_steady(space, fluid, _bc(200), True, continuation="off")
    flow = solve_steady(space, fluid, _bc(200), True)
    stages = flow.report.continuation
    assert stages and stages[-1]["factor"] == 1.0 and stages[-1]["converged"]
    low = solve_steady(space, fluid, _bc(100), True)
    other = solve_steady(space, fluid, _bc(200), True, initial=low, continuation="off")
    assert not other.report.continuation
    F, F_other = flow.force("particle0")[1], other.force("particle0")[1]
    assert F > 0 and abs(F / F_other - 1) < 1e-9
    again = solve_steady(space, fluid, _bc(200), True, initial=flow, continuation="off")
    assert again.report.iterations <= 2
