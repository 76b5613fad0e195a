"""The coupled remesh graded by the flow (``CoupledStepper.flow_sizing``): finer where
the fluid turns, the same mesh for the same flow, a clear error on a mesh kind that
takes no outside size."""

from dataclasses import replace

import numpy as np
import pytest

import meshing
from skfem_granular.coupled.flow_size import FlowSizing
from skfem_granular.scene import Scene
from skfem_granular.simulation import Simulation


def _sim(kind):
    return Simulation(Scene.from_dict({
        "domain": {"box": [0.0, 0.0, 3e-3, 11e-3]},
        "fluid": {"density": 1000.0, "viscosity": 1e-3},
        "particles": [{"sides": 24, "radius": 0.5e-3, "center": [1.5e-3, 7.5e-3],
                       "density": 2650.0}],
        "mesh": {"kind": kind},
        "time": {"t_end": 1e-3, "dt": 1e-4}}, name="flow_sizing"))


def _vortex(space):
    """A vortex 2.5 mm below the disk's centre (the fluid state the remesh transfers)."""
    X = space.sb.doflocs
    g = np.exp(-((X[0] - 1.5e-3) ** 2 + (X[1] - 5e-3) ** 2) / (0.4e-3) ** 2)
    u = np.empty(space.nu)
    u[0::2], u[1::2] = -(X[1] - 5e-3) * g * 100.0, (X[0] - 1.5e-3) * g * 100.0
    return u


def _remeshed(sizing):
    sim = _sim("field")
    st = sim.stepper
    st.flow_sizing = sizing
    st.state = replace(st.state, u_n=_vortex(st.space))
    st.remesh()
    return st.mesh, st


def test_remesh_follows_the_flow_and_is_deterministic():
    plain, _ = _remeshed(None)
    fine, st = _remeshed(FlowSizing(eps=0.1, budget=4000))
    again, _ = _remeshed(FlowSizing(eps=0.1, budget=4000))
    np.testing.assert_array_equal(fine.p, again.p)
    near = lambda m: int(np.sum(np.hypot(m.p[0] - 1.5e-3, m.p[1] - 5e-3) < 0.5e-3))  # noqa: E731
    assert near(fine) > 4 * near(plain)
    assert st.remeshes == 1
    assert meshing.mesh_stats(fine).min_angle >= 20.0
    assert st.state.u_n.shape == (st.space.nu,)      # the fluid moved onto it


def test_flow_sizing_needs_a_field_mesh():
    sim = _sim("graded")
    sim.stepper.flow_sizing = FlowSizing()
    with pytest.raises(ValueError, match="flow_sizing: needs a 'field' mesh"):
        sim.stepper.remesh()
