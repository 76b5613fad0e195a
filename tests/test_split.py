"""The split coupling against analytic added mass, the monolithic coupling and its own
projection (docs/validation.md case 7; the design page's split solver)."""

from dataclasses import replace

import numpy as np
import pytest
from helpers import released_cylinder, resumed_between_checkpoints

import skfem_granular as sg
from skfem_granular.coupled import MonolithicCoupling, RigidBodies, StepProblem
from skfem_granular.coupled.split import SplitCoupling, SplitOptions
from skfem_granular.scene import Scene
from skfem_granular.simulation import Simulation
from skfem_granular.timestep import BDF2

A_IN, B_OUT, G = 1e-3, 2e-3, 9.81
N_SEG = 64


@pytest.fixture(scope="module")
def released():
    """A cylinder at rest inside a fixed concentric cylinder (water)."""
    return released_cylinder(A_IN, B_OUT, N_SEG)


def _coupling(space, area, rho_p, cls, **kw):
    m = rho_p * area
    bodies = RigidBodies(np.zeros((2, 1)), [m], [0.5 * m * A_IN**2])
    return cls(space, sg.Fluid(1000.0, 1e-3), {"wall": (0.0, 0.0)}, bodies, **kw)


def _weight(area, rho_p):
    return np.array([[0.0], [-(rho_p - 1000.0) * area * G]])


def _first_step(coupling, space, F_ext, dt):
    return coupling.step(StepProblem(bdf2=BDF2(dt), t_new=dt, u_n=np.zeros(space.nu),
                                     xi_n=np.zeros((3, 1)), F_ext=F_ext, T_ext=np.zeros(1)))


@pytest.mark.parametrize("ratio", [2.65, 0.5, 0.1, 0.01])
def test_release_matches_added_mass_and_the_monolithic_step(released, ratio):
    """A first step (no pressure yet) is solved until it is the monolithic step, so
    the acceleration at release is the added-mass value (C_a = (b^2 + a^2)/(b^2 - a^2)),
    also for grains 100x lighter than the fluid, where a staggered scheme diverges."""
    space, area = released
    rho_p, dt = 1000.0 * ratio, 1e-5
    split = _first_step(_coupling(space, area, rho_p, SplitCoupling), space,
                        _weight(area, rho_p), dt)
    mono = _first_step(_coupling(space, area, rho_p, MonolithicCoupling), space,
                       _weight(area, rho_p), dt)
    Ca = (B_OUT**2 + A_IN**2) / (B_OUT**2 - A_IN**2)
    exact = -G * (rho_p - 1000.0) / (rho_p + Ca * 1000.0)
    assert split.xi[1, 0] / dt == pytest.approx(exact, rel=0.03)
    assert split.xi[1, 0] == pytest.approx(mono.xi[1, 0], rel=1e-5)
    assert split.force[1, 0] == pytest.approx(mono.force[1, 0], rel=1e-4)
    assert split.iterations > 1  # corrected, not a single pass


def test_a_single_pass_underestimates_the_added_mass(released):
    """In one pass the first step's added mass is that of the lumped projection mass
    (0.85 diag(M)): the acceleration is too large by more than 10 %. This is why a run's
    first step is solved to the monolithic step."""
    space, area = released
    rho_p, dt = 1100.0, 1e-5
    options = SplitOptions(start_iterations=0)
    one = _first_step(_coupling(space, area, rho_p, SplitCoupling, options=options), space,
                      _weight(area, rho_p), dt)
    mono = _first_step(_coupling(space, area, rho_p, MonolithicCoupling), space,
                       _weight(area, rho_p), dt)
    assert one.iterations == 1
    assert abs(one.xi[1, 0] / mono.xi[1, 0] - 1) > 0.1


def test_the_step_velocity_is_discretely_divergence_free(released):
    """On the mesh as built the projection is solved with its factors: B u = 0 on every
    free pressure to round-off after a pass."""
    space, area = released
    c = _coupling(space, area, 2650.0, SplitCoupling,
                  options=SplitOptions(start_iterations=0))
    res = _first_step(c, space, _weight(area, 2650.0), 1e-4)
    u = res.x[: space.nu]
    div = (space.B @ u)[1:]  # the first pressure DOF is pinned
    assert np.abs(div).max() <= 1e-12 * np.abs(space.B).sum(axis=1).max() * np.abs(u).max()


def _sinking(scheme, dt, t_end=2e-3, density=None):
    sc = Scene.bundled("single_particle")
    if density is not None:
        sc = replace(sc, particles=[replace(p, density=density) for p in sc.particles])
    sc = replace(sc, coupling=scheme, output_dir=None, newton_tol=1e-10,
                 time=replace(sc.time, t_end=t_end, dt=dt))
    sim = Simulation(sc)
    speeds = [sim.dem.particles.v[1, 0] for _ in sim.evolve()]
    return np.array(speeds)


@pytest.fixture(scope="module")
def sinking():
    """The paper's single particle (graded mesh, moving with the particle) over 2 ms at
    three fixed steps, split and monolithic."""
    return {(dt, s): _sinking(s, dt) for dt in (1e-4, 5e-5, 2.5e-5)
            for s in ("monolithic", "split")}


def test_split_follows_the_monolithic_sinking_particle(sinking):
    """v_y of the paper's particle at 2 ms within 1e-4 of the monolithic step's, at each
    step size (the issue's bound: 0.5 %), and the difference is below the monolithic
    run's own time-step error (its change from dt to dt/4)."""
    for dt in (1e-4, 5e-5, 2.5e-5):
        mono, split = sinking[(dt, "monolithic")][-1], sinking[(dt, "split")][-1]
        assert split == pytest.approx(mono, rel=1e-4)
    bdf2_error = abs(sinking[(1e-4, "monolithic")][-1] - sinking[(2.5e-5, "monolithic")][-1])
    assert abs(sinking[(1e-4, "split")][-1] - sinking[(1e-4, "monolithic")][-1]) < bdf2_error


def test_splitting_error_is_second_order_in_time(sinking):
    """The split's difference from the monolithic step at the same step sizes falls as
    dt^2 (measured orders 2.02 and 2.00 over dt = 1e-4, 5e-5, 2.5e-5 s; 1.83 and 1.91 with
    the code before edge-flip repairs and the predictor's tolerance of 1e-4)."""
    err = [abs(sinking[(dt, "split")][-1] - sinking[(dt, "monolithic")][-1])
           for dt in (1e-4, 5e-5, 2.5e-5)]
    orders = np.log2(np.array(err[:-1]) / np.array(err[1:]))
    assert np.all(orders >= 1.8), orders


def test_split_is_second_order_in_time_on_its_moving_mesh(sinking):
    """Temporal self-convergence of the split step on the paper's moving (ALE) mesh: v_y
    at 2 ms at dt = 1e-4 ... 1.25e-5 s, the differences of successive levels falling as
    dt^2 (measured orders 2.00 and 2.00; the monolithic run's 2.01 and 2.00)."""
    v = [sinking[(dt, "split")][-1] for dt in (1e-4, 5e-5, 2.5e-5)]
    v.append(_sinking("split", 1.25e-5)[-1])
    d = np.abs(np.diff(v))
    orders = np.log2(d[:-1] / d[1:])
    assert np.all(np.abs(orders - 2.0) < 0.2), orders


def test_a_light_particle_rises_stably_on_the_split_path():
    """A particle a tenth as dense as the fluid rises: no added-mass instability over 200
    steps, and its speed at 2 ms is the monolithic run's to 1e-3."""
    split = _sinking("split", 1e-5, density=100.0)
    mono = _sinking("monolithic", 1e-5, density=100.0)
    assert np.all(np.isfinite(split)) and np.all(np.diff(split) > 0)  # accelerating upwards
    assert split[-1] == pytest.approx(mono[-1], rel=1e-3)


def test_checkpoint_at_any_step_resumes_bit_for_bit(tmp_path):
    """A checkpoint between two steps (as SIGTERM writes one): the resumed split run
    factorises the projection where the writer held it, so its GMRES iterates, and the
    run, are the uninterrupted run's."""
    base = Scene.bundled("single_particle")
    sc = replace(base, coupling="split", time=replace(base.time, t_end=3e-4))
    ref, res = resumed_between_checkpoints(sc, tmp_path, 13)
    for c in ("vy", "angle", "omega", "Fy", "torque"):
        assert np.array_equal(getattr(ref, c), getattr(res, c)), c


def test_contacts_and_remeshing_resume_bit_for_bit(tmp_path):
    """Two hexagons landing on the floor (contacts, backward-Euler steps, remeshes) on the
    split path: finite, and a resumed run equals the uninterrupted one."""
    data = {"domain": {"box": [0.0, 0.0, 6e-3, 4e-3]},
            "fluid": {"density": 1000.0, "viscosity": 1e-3},
            "grid": {"nx": 2, "ny": 1, "sides": 6, "radius": 0.5e-3, "spacing": 1.1e-3,
                     "origin": [2.4e-3, 0.437e-3], "density": 2650.0, "core_ratio": 0.8},
            "mesh": {"kind": "group", "delta_l": 0.2e-3},
            "time": {"t_end": 14 * 2e-4, "dt": 2e-4, "dem_dt": None},
            "coupling": {"scheme": "split", "remesh_travel": 0.01}}
    data["time"].pop("dem_dt")
    scene = Scene.from_dict(data, name="floor")
    full = Simulation(replace(scene, checkpoint_every=7), output_dir=tmp_path / "full")
    h_full = full.run(progress=False).history
    part = Simulation(replace(scene, checkpoint_every=7,
                              time=replace(scene.time, t_end=7 * 2e-4)),
                      output_dir=tmp_path / "part")
    part.run(progress=False)
    h_res = Simulation.resume(tmp_path / "part", t_end=14 * 2e-4).run(progress=False).history
    assert full.remeshes >= 1 and full.contacts_active
    for c in ("vy", "vx", "omega", "Fy", "torque"):
        assert np.all(np.isfinite(getattr(h_full, c)))
        assert np.array_equal(getattr(h_full, c), getattr(h_res, c)), c


def _column(scheme, dt, t_end):
    from helpers import column_packing

    from skfem_granular.collapse import column_scene

    sc = column_scene(column_packing("dense"), fluid=True, core_ratio=0.9, t_end=t_end, dt=dt)
    sim = Simulation(replace(sc, coupling=scheme, output_dir=None))
    for _ in sim.evolve(progress=False):
        pass
    v = sim.dem.particles.v
    return v[1].mean(), 0.5 * (sim.dem.mass * (v[:2] ** 2).sum(axis=0)).sum()


def test_an_immersed_column_in_contact_converges_to_the_monolithic_run():
    """30 grains released in water, every step a backward-Euler contact step: at the
    collapse's step (0.2 ms) the split's mean grain velocity and kinetic energy at 6 ms
    differ from the monolithic run's by 0.9 % and 1.9 %, as the monolithic run's own differ from its
    run at a quarter of the step (2.4 %, 1.7 %); at 50 us the two agree within 0.5 %
    (at 3 ms, here: 0.08 % and 0.11 %)."""
    mono = np.array(_column("monolithic", 5e-5, 3e-3))
    split = np.array(_column("split", 5e-5, 3e-3))
    assert split == pytest.approx(mono, rel=5e-3)


def test_a_run_continues_on_the_other_solver(tmp_path):
    """A monolithic run resumed on the split solver (and back) goes on from its state:
    the paper's particle's v_y at 0.3 ms within 1e-4 of the run that never switched."""
    base = Scene.bundled("single_particle")
    sc = replace(base, checkpoint_every=15, time=replace(base.time, t_end=3e-4))
    ref = Simulation(sc, output_dir=tmp_path / "ref").run(progress=False).history
    Simulation(replace(sc, time=replace(sc.time, t_end=1.5e-4)),
               output_dir=tmp_path / "part").run(progress=False)
    res = Simulation.resume(tmp_path / "part", t_end=3e-4, coupling="split")
    assert res.scene.coupling == "split"
    h = res.run(progress=False).history
    assert len(h) == len(ref)
    assert h.vy[-1] == pytest.approx(ref.vy[-1], rel=1e-4)
    with pytest.raises(ValueError, match="coupling = 'magic'"):
        Simulation.resume(tmp_path / "part", coupling="magic")


@pytest.mark.slow
def test_settling_disk_on_the_split_path():
    """The validation page's settling disk (Re about 17) on the split solver, to the floor:
    v_y against Koblitz et al.'s curve (relative L2 over [0, 0.7 s] within 1 %), its speed
    at 0.5 s (near its peak) and the time its centre is two radii above the floor within
    1e-4 of the monolithic run's (regression pins of that run: 5.5588 cm/s and 0.7534 s,
    tests/test_curves.py; the issue asked for 0.5 %). Measured: L2 0.00443 (monolithic
    0.00443), peak 5.56893 cm/s at 0.6 s (1.4e-7 from the monolithic run's), floor at
    0.753417 s (0.753422 s)."""
    from skfem_granular.scene import TimeSpec
    from skfem_granular.validation import curves

    sc = Scene.bundled("settling_disk_channel")
    sc = replace(sc, coupling="split", time=TimeSpec(t_end=0.8, dt=1e-3), output_dir=None)
    h = Simulation(sc).run(progress=False).history
    t, y, vy = h.t, h.y[:, 0], h.vy[:, 0]
    k = curves.load_curve("koblitz2017_settling_vy")
    assert curves.l2_difference(t, vy, *k.series("vy"), interval=(0.0, 0.7)).relative < 0.01
    assert -np.interp(0.5, t, vy) == pytest.approx(0.0555882, rel=1e-4)
    out = curves.compare_settling(t, y, vy, k, y_stop=2.5e-3, y0=0.04)
    assert out["t_floor"]["run"] == pytest.approx(0.753422, rel=1e-4)


def test_a_dropped_split_coupling_is_freed_without_the_cycle_collector():
    """A remeshed-away split coupling, its projection and factors and its space are freed
    by reference counting (a cycle through the projection kept them until the cyclic
    collector ran: a 200-grain column's peak memory grew 350-400 MB a remesh, 2.2 GB after
    4 remeshes against 1.0 GB without it)."""
    import gc
    import weakref

    from helpers import box, regular_polygon

    mesh = box(0.0, 0.0, 1.0, 1.0, 0.05, hole=regular_polygon(12, 0.2, (0.5, 0.5)))
    space = sg.TaylorHood(mesh)
    c = SplitCoupling(space, sg.Fluid(1.0, 1.0), {"wall": (0.0, 0.0)},
                      RigidBodies(np.array([[0.5], [0.5]]), [1.0], [1.0]))
    c.step(StepProblem(bdf2=BDF2(1e-2), t_new=1e-2, u_n=np.zeros(space.nu),
                       xi_n=np.zeros((3, 1)), F_ext=np.array([[0.0], [-1.0]]), T_ext=np.zeros(1)))
    assert c.projection.factorizations == 1
    alive = [weakref.ref(o) for o in (c, c.projection, space, c.op)]
    enabled = gc.isenabled()
    gc.disable()
    try:
        del c, space
        assert [r() is None for r in alive] == [True] * 4
    finally:
        if enabled:
            gc.enable()
