"""User terms (scikit-fem forms) in coupled runs: the paper's single particle, 0.2 ms.

- a BilinearForm that is half the built-in viscous term, with the fluid's viscosity
  halved, gives the compiled run's particle velocities to round-off;
- a LinearForm body force density ``f(t)`` on the fluid (the built-in equations leave
  the fluid's weight out: pressures are dynamic) is balanced by the hydrostatic
  pressure ``p = f . x`` (P1 holds it exactly), which pushes on the particle with
  ``-f A_core``: the run equals one with that force on the particle as a DEM force
  callback, and with ``f = rho_f g`` the particle, in creeping flow, sinks at
  ``(rho_p - 2 rho_f) / (rho_p - rho_f)`` of its velocity.
"""

import shutil
from dataclasses import replace

import numpy as np
import pytest
from skfem import BilinearForm, LinearForm
from skfem.helpers import ddot, sym_grad

from skfem_granular import Fluid, UserTerms
from skfem_granular.scene import Scene, TimeSpec
from skfem_granular.simulation import Simulation

T_END = 2e-4


@pytest.fixture(scope="module")
def scene():
    sc = replace(Scene.bundled("single_particle"), output_dir=None)
    return replace(sc, time=TimeSpec(t_end=T_END, dt=sc.time.dt))


def vy(scene, terms=None, force=None) -> np.ndarray:
    """The particle's vertical velocity after every step (``force(sim, t)``: a DEM force
    callback's force ``(2, K)``)."""
    sim = Simulation(scene, terms=terms)
    if force is not None:
        sim.dem.force_callbacks.append(lambda dem, t: (force(sim, t), np.zeros(dem.n)))
    return np.array(sim.run(progress=False).history.vy)


@pytest.fixture(scope="module")
def reference(scene):
    return vy(scene)


def test_user_viscous_term_equals_the_compiled_one(scene, reference):
    """Half the viscosity compiled, half as a user BilinearForm: the same run (measured
    2e-16 relative: the same matrices to round-off, the same chord iterates)."""
    eta = scene.fluid.viscosity
    half = replace(scene, fluid=Fluid(density=scene.fluid.density, viscosity=eta / 2))
    viscous = BilinearForm(lambda u, v, w: (eta / 2) * 2.0 * ddot(sym_grad(u), sym_grad(v)))
    v = vy(half, UserTerms(momentum=[viscous]))
    assert np.abs(v / reference - 1.0).max() < 1e-10


def test_user_body_force_pushes_the_particle_by_its_hydrostatic_pressure(scene, reference):
    """A time-dependent uniform force density on the fluid: the run equals the run with
    ``-f(t) A_core`` on the particle (measured 4e-15 relative); with ``f = rho_f g`` the
    particle sinks at 650 / 1650 of its velocity (creeping flow: velocity proportional to
    the net force, as in test_dem_force_callbacks_act_in_coupled_runs)."""
    rho_g = scene.fluid.density * np.asarray(scene.gravity)

    def f(t):
        return rho_g * (1.0 + 0.5 * np.sin(2 * np.pi * t / T_END))

    @LinearForm
    def fluid_force(v, w):
        fx, fy = f(w["t"])
        return fx * v[0] + fy * v[1]

    def on_particle(sim, t):
        return -np.outer(f(t), sim.stepper.core_area)

    v_form = vy(scene, UserTerms(momentum=fluid_force))
    v_callback = vy(scene, force=on_particle)
    assert np.abs(v_form / v_callback - 1.0).max() < 1e-10
    weight = LinearForm(lambda v, w: rho_g[0] * v[0] + rho_g[1] * v[1])
    v_weight = vy(scene, UserTerms(momentum=weight))
    rho_p, rho_f = scene.particles[0].density, scene.fluid.density  # 2650, 1000
    assert np.abs(v_weight / reference - (rho_p - 2 * rho_f) / (rho_p - rho_f)).max() < 1e-6


def test_user_viscous_term_in_the_partitioned_coupling(scene):
    """The paper's partitioned coupling, 0.1 ms: the same check as the monolithic one
    (measured 4e-16 relative)."""
    short = replace(scene, coupling="partitioned",
                    time=TimeSpec(t_end=1e-4, dt=scene.time.dt))
    eta = scene.fluid.viscosity
    half = replace(short, fluid=Fluid(density=scene.fluid.density, viscosity=eta / 2))
    viscous = BilinearForm(lambda u, v, w: (eta / 2) * 2.0 * ddot(sym_grad(u), sym_grad(v)))
    reference = vy(short)
    assert np.abs(vy(half, UserTerms(momentum=[viscous])) / reference - 1.0).max() < 1e-10


def test_resumed_run_with_user_terms_continues_the_same(scene, tmp_path):
    """A checkpoint does not hold the user forms: given again to ``Simulation.resume`` the
    resumed run reproduces the uninterrupted one bit for bit (10 + 10 steps)."""
    rho_g = scene.fluid.density * np.asarray(scene.gravity)
    terms = UserTerms(momentum=LinearForm(lambda v, w: rho_g[0] * v[0] + rho_g[1] * v[1]))
    dt = scene.time.dt

    def timed(t_end):
        return replace(scene, time=TimeSpec(t_end=t_end, dt=dt), checkpoint_every=10,
                       vtu_every=0)

    full = Simulation(timed(20 * dt), output_dir=tmp_path / "full", terms=terms)
    v_full = np.array(full.run(progress=False).history.vy)
    Simulation(timed(10 * dt), output_dir=tmp_path / "part", terms=terms).run(progress=False)
    shutil.copytree(tmp_path / "part", tmp_path / "part_plain")
    resumed = Simulation.resume(tmp_path / "part", t_end=20 * dt, terms=terms)
    v_res = np.array(resumed.run(progress=False).history.vy)
    assert np.array_equal(v_full, v_res)
    # without the forms the continued steps differ (the extra buoyancy is gone)
    plain = Simulation.resume(tmp_path / "part_plain", t_end=20 * dt)
    v_plain = np.array(plain.run(progress=False).history.vy)
    assert np.array_equal(v_plain[:10], v_full[:10])
    assert np.all(np.abs(v_plain[10:] / v_full[10:] - 1.0) > 1e-3)
