"""Scene -> Simulation: the paper's single particle, effects, bad input, CLI."""

import json
from dataclasses import replace

import numpy as np
import pytest

from skfem_granular.cli import main
from skfem_granular.scene import Effects, Scene, TimeSpec, bundled
from skfem_granular.simulation import Simulation

SCENES = bundled("single_particle").parent  # the bundled scenes (skfem_granular/scene/library)


def _short(scene, t_end=1e-4, **kw):
    return replace(scene, time=TimeSpec(t_end=t_end, dt=scene.time.dt), output_dir=None, **kw)


@pytest.fixture(scope="module")
def paper():
    """The paper's single particle, writing no files unless given a folder."""
    return replace(Scene.from_toml(SCENES / "single_particle.toml"), output_dir=None)


def test_single_particle_sinks_with_effects_listed(paper, tmp_path):
    res = Simulation(_short(paper), output_dir=tmp_path).run(progress=False)
    s = res.summary
    assert s["effects"] == {
        "fluid": True,
        "gravity": True,
        "convection": True,
        "contacts": False,
        "rotation": True,
        "remeshing": True,
    }
    h = res.history
    assert len(h) == 10 and h.t[-1] == pytest.approx(1e-4)
    # early times: the particle accelerates downwards at less than the added-mass limit
    rho_p, rho_f = 2650.0, 1000.0
    a_limit = 9.81 * (rho_p - rho_f) / (rho_p + rho_f)  # C_a = 1, unbounded fluid
    assert np.all(h.vy[:, 0] < 0) and np.all(np.diff(h.vy[:, 0]) < 0)
    assert 0 < -h.ay[0, 0] < a_limit * 1.05
    # momentum balance of the particle: m a = F_fluid + (m - rho_f A) g
    area = np.pi * 0.5e-3**2 * (24 / (2 * np.pi)) * np.sin(2 * np.pi / 24)
    m = rho_p * area
    np.testing.assert_allclose(m * h.ay[1:, 0], h.Fy[1:, 0] - (m - rho_f * area) * 9.81, rtol=1e-8)
    # output: VTU series, history and summary
    assert (tmp_path / "flow.pvd").exists() and (tmp_path / "particles.pvd").exists()
    assert json.loads((tmp_path / "summary.json").read_text())["steps"] == 10
    table = np.loadtxt(tmp_path / "history.csv", delimiter=",", skiprows=1)
    assert table.shape[0] == 10


def test_symmetric_mesh_keeps_horizontal_motion_at_round_off(paper):
    """validation case 8 on the mirror-symmetric graded mesh: drift is rounding alone."""
    h = Simulation(_short(paper)).run(progress=False).history
    assert np.abs(h.vx).max() < 1e-13 * np.abs(h.vy).max()
    assert np.abs(h.x[:, 0] - 1.5e-3).max() < 1e-15


def test_graded_and_uniform_agree_early(paper):
    g = Simulation(_short(paper, t_end=5e-5)).run(progress=False).history
    u = Simulation(_short(paper, t_end=5e-5).with_mesh("uniform")).run(progress=False).history
    np.testing.assert_allclose(g.vy[:, 0], u.vy[:, 0], rtol=0.02)


def test_neutrally_buoyant_particle_stays_at_rest(paper):
    p = replace(paper.particles[0], density=1000.0)
    res = Simulation(_short(replace(paper, particles=(p,)))).run(progress=False)
    h = res.history
    # weight and buoyancy cancel up to round-off (mass from the DEM, volume from the core
    # outline: 2e-16 g measured), so the particle gains at most round-off speed
    assert np.abs(h.vy[:, 0]).max() < 1e-14 * 9.81 * h.t[-1]
    assert np.abs(h.vx).max() < 1e-14 * 9.81 * h.t[-1]


def test_dry_scene_builds_no_mesh(paper):
    dry = replace(_short(paper, t_end=1e-3), fluid=None)
    sim = Simulation(dry)
    assert not hasattr(sim, "mesh")
    h = sim.run(progress=False).history
    assert h.vy[-1, 0] == pytest.approx(-9.81 * 1e-3, rel=1e-9)  # free fall


def test_stokes_scene_uses_one_factorisation(paper):
    """On a fixed mesh (a moving one changes the operator every step)."""
    sc = _short(paper, effects=Effects(convection=False), mesh_motion="fixed")
    sim = Simulation(sc)
    res = sim.run(progress=False)
    assert sim.coupling.solver.stats.factorizations == 2  # backward Euler, then BDF2
    assert np.all(res.history.iterations == 1)


def test_warning_when_convection_off_at_high_reynolds(paper):
    sc = _short(paper, t_end=0.05, effects=Effects(convection=False))
    sc = replace(sc, time=TimeSpec(t_end=0.05, dt=1e-3))
    warnings = Simulation(sc).warnings
    assert any("Reynolds" in w for w in warnings)


@pytest.mark.parametrize("motion", ["fixed", "ale"])
def test_remeshing_keeps_velocity_continuous(paper, motion):
    p = replace(paper.particles[0], velocity=(0.0, -0.05))
    sc = replace(
        paper,
        particles=(p,),
        time=TimeSpec(t_end=2e-3, dt=1e-4),
        effects=Effects(gravity=False),
        remesh_fraction=0.1,
        mesh_motion=motion,
        remesh_travel=0.05,  # ALE: remesh after 5 % of the radius (several times here)
    )
    sim = Simulation(sc)
    h = sim.run(progress=False).history
    assert sim.remeshes >= 2
    # a decelerating particle: the speed falls smoothly, without jumps at remeshes
    dv = np.diff(h.vy[:, 0])
    assert np.all(dv > 0)
    assert np.abs(np.diff(dv[1:])).max() < 0.5 * np.abs(dv[1:]).max()


BAD = [
    ({"time": {"dt": -1.0}}, "time.dt"),
    ({"time": {"t_end": float("nan")}}, "time.t_end"),
    ({"time": {"t_end": 1e-3, "dt": 1e-2}}, "time.dt"),
    ({"fluid": {"density": 0.0, "viscosity": 1e-3}}, "fluid.density"),
    ({"fluid": {"density": 1000.0, "viscosity": -1.0}}, "fluid.viscosity"),
    ({"effects": {"convection": "yes"}}, "effects.convection"),
    ({"effects": {"warp": True}}, "unknown key 'warp'"),
    ({"mesh": {"kind": "hex"}}, "mesh.kind"),
    ({"mesh": {"kind": "graded", "sigma": 0.9}}, "mesh.sigma"),
    ({"coupling": {"scheme": "magic"}}, "coupling.scheme"),
    ({"domain": {"box": [0, 0, -1, 1]}}, "domain.box"),
    ({"nonsense": {}}, "unknown key 'nonsense'"),
]


@pytest.mark.parametrize("patch,field", BAD)
def test_bad_scene_values_name_the_field(paper, patch, field):
    base = {
        "domain": {"box": [0.0, 0.0, 3e-3, 11e-3]},
        "fluid": {"density": 1000.0, "viscosity": 1e-3},
        "particles": [
            {"sides": 24, "radius": 0.5e-3, "center": [1.5e-3, 5.5e-3], "density": 2650.0}
        ],
    }
    base.update(patch)
    with pytest.raises(ValueError, match=field.replace(".", r"\.")):
        Scene.from_dict(base)


def test_particle_outside_domain(paper):
    data = {
        "domain": {"box": [0.0, 0.0, 3e-3, 11e-3]},
        "particles": [{"sides": 6, "radius": 1e-3, "center": [0.5e-3, 5e-3], "density": 2650.0}],
    }
    with pytest.raises(ValueError, match=r"particles\[0\]"):
        Scene.from_dict(data)


def test_cli_bad_input_exit_code(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("[domain]\nbox = [0, 0, 1, 1]\n[time]\ndt = -1\n")
    assert main(["run", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "time.dt" in err[0]


def test_cli_runs_scene(tmp_path, capsys):
    code = main(
        [
            "run",
            str(SCENES / "single_particle.toml"),
            "--out",
            str(tmp_path),
            "--t-end",
            "3e-5",
            "--no-progress",
        ]
    )
    assert code == 0
    out = capsys.readouterr().out
    assert "734 P2 nodes" in out and "vy =" in out
    assert (tmp_path / "history.csv").exists()


@pytest.mark.slow
def test_paper_single_particle_fine_vs_graded(paper):
    """Paper Section 6, full 1 ms: vertical velocity curves within 2 % of each other."""
    g = Simulation(paper).run(progress=False)
    u = Simulation(paper.with_mesh("uniform")).run(progress=False)
    vg, vu = g.history.vy[:, 0], u.history.vy[:, 0]
    assert np.abs(vg - vu).max() < 0.02 * np.abs(vu).max()


@pytest.mark.parametrize("motion", ["fixed", "ale"])
def test_grains_on_the_floor_contacts_and_remeshing(tmp_path, motion):
    """A 2 x 2 block of hexagons just above the floor: contacts, DEM subcycling, remeshing."""
    import meshing

    data = {
        "domain": {"box": [0.0, 0.0, 6e-3, 4e-3]},
        "fluid": {"density": 1000.0, "viscosity": 1e-3},
        "grid": {
            "nx": 2,
            "ny": 2,
            "sides": 6,
            "radius": 0.5e-3,
            "spacing": 1.1e-3,
            "origin": [2.4e-3, 0.437e-3],
            "density": 2650.0,
            "core_ratio": 0.8,
        },
        "mesh": {"kind": "group", "delta_l": 0.2e-3},
        "time": {"t_end": 5e-3, "dt": 2e-4},
        "coupling": {"remesh_fraction": 0.05, "mesh_motion": motion, "remesh_travel": 0.02},
    }
    sc = Scene.from_dict(data, name="floor")
    sim = Simulation(sc, output_dir=tmp_path)
    assert sim.contacts_active
    res = sim.run(progress=False)
    h = res.history
    assert np.all(np.isfinite(h.vy))
    assert np.all(h.contacts[:, :2].max(axis=0) >= 1)  # both bottom grains reach the floor
    # the floor stops them: their speed falls far below that of the grains still sinking
    assert np.abs(h.vy[-3:, :2]).max() < 0.3 * np.abs(h.vy[-1, 2:]).min()
    assert sim.remeshes >= 1
    # the fluid domain is the box minus the cores, exactly, on every new mesh
    cores = sim.dem.core_outlines()
    area = 6e-3 * 4e-3 - sum(
        0.5 * np.sum(c[0] * np.roll(c[1], -1) - np.roll(c[0], -1) * c[1]) for c in cores
    )
    assert sim.space.ub.dx.sum() == pytest.approx(area, rel=1e-12)
    assert meshing.mesh_stats(sim.mesh).n_inverted == 0
    # the floor holds the bottom grains: overlap stays a small fraction of their size
    assert min(s[1].min() for s in sim.dem.shadow_outlines()) > -0.05e-3


def test_failed_step_is_retried_with_half_the_step(paper, monkeypatch):
    from skfem_granular.fluid import ConvergenceError

    sim = Simulation(_short(paper, t_end=5e-5))
    real = sim.coupling.step
    calls = {"n": 0}

    def flaky(problem):
        calls["n"] += 1
        if calls["n"] == 2:
            raise ConvergenceError("injected")
        return real(problem)

    monkeypatch.setattr(sim.coupling, "step", flaky)
    h = sim.run(progress=False).history
    assert sim.retries == 1
    assert h.t[-1] == pytest.approx(5e-5, rel=1e-12)
    assert h.dt[1] == pytest.approx(0.5e-5)  # the retried step
    assert np.all(h.dt[1:] / h.dt[:-1] <= 2.0 + 1e-12)  # growth back capped


def test_run_that_cannot_converge_stops_with_history_written(paper, tmp_path):
    from skfem_granular.coupled.stepper import MAX_RETRIES, SimulationError

    sim = Simulation(_short(paper, t_end=5e-5), output_dir=tmp_path)
    sim.coupling.max_iterations = 1  # Navier-Stokes cannot converge in one chord step
    with pytest.raises(SimulationError, match="run stopped at t=0"):
        sim.run(progress=False)
    assert sim.retries == MAX_RETRIES
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert "run stopped" in summary["failed"]
    assert (tmp_path / "history.csv").exists() and (tmp_path / "flow.pvd").exists()


def test_run_without_a_folder_that_cannot_converge_says_where_its_state_is(paper):
    """With no output folder the failure names no folder (it said 'written to None')."""
    from skfem_granular.coupled.stepper import SimulationError

    sim = Simulation(_short(paper, t_end=5e-5), output_dir=None)
    sim.coupling.max_iterations = 1
    with pytest.raises(SimulationError, match="no output folder: the last good state is in "
                                              "sim.last_good") as err:
        sim.run(progress=False)
    assert "None" not in str(err.value)
    assert sim.last_good.t == 0.0


def test_cli_adaptive_run(tmp_path, capsys):
    """--tol turns adaptive steps on; the summary line says how the steps went."""
    code = main(["run", str(SCENES / "single_particle.toml"), "--out", str(tmp_path),
                 "--t-end", "1e-4", "--tol", "1e-4", "--no-progress"])
    assert code == 0
    out = capsys.readouterr().out
    assert "adaptive (dt " in out and "rejected)" in out
    import json

    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["adaptive"] and s["dt_range"][0] <= s["dt_range"][1] <= 1e-5
    h = np.genfromtxt(tmp_path / "history.csv", delimiter=",", names=True)
    err = h["error"][np.isfinite(h["error"])]
    assert err.size > 0 and err.max() <= 1e-4


def test_cli_resume_refuses_tol(tmp_path, capsys):
    assert main(["run", "--resume", str(tmp_path), "--tol", "1e-3"]) == 2
    assert "--tol" in capsys.readouterr().err


def test_generator_loop_is_the_run(paper, tmp_path):
    """The README's loop: ``for t, step in sim.evolve()`` yields every accepted step, the
    same numbers as ``run()`` (bit for bit), and writes history and summary when it ends."""
    ref = Simulation(_short(paper)).run(progress=False).history
    sim = Simulation(_short(paper), output_dir=tmp_path)
    seen = []
    for t, step in sim.evolve():
        seen.append((t, sim.dem.velocities[1, 0], step.force[1, 0], step.acceleration[1, 0]))
    t, vy, Fy, ay = np.array(seen).T
    assert len(seen) == len(ref) == 10
    assert np.array_equal(t, ref.t) and np.array_equal(vy, ref.vy[:, 0])
    assert np.array_equal(Fy, ref.Fy[:, 0]) and np.array_equal(ay, ref.ay[:, 0])
    assert np.array_equal(sim.result.history.vy, ref.vy)
    h = np.genfromtxt(tmp_path / "history.csv", delimiter=",", names=True)
    assert np.array_equal(h["vy_0"], ref.vy[:, 0])  # written to full precision
    assert json.loads((tmp_path / "summary.json").read_text())["steps"] == 10


def test_generator_loop_broken_off_keeps_what_it_did(paper, tmp_path):
    """Closing the generator after 3 steps leaves a 3-row history and a summary."""
    from contextlib import closing

    sim = Simulation(_short(paper), output_dir=tmp_path)
    with closing(sim.evolve()) as steps:
        for k, _ in enumerate(steps, start=1):
            if k == 3:
                break
    assert len(sim.result.history) == 3
    h = np.genfromtxt(tmp_path / "history.csv", delimiter=",", names=True)
    assert h.shape == (3,) and json.loads((tmp_path / "summary.json").read_text())["steps"] == 3


def test_summary_counts_factorisations_by_kind():
    """A constant-step run factorises the BDF2-Stokes operator twice (the backward-Euler
    start, then BDF2) and never needs a Newton Jacobian on the paper's particle."""
    sc = replace(Scene.bundled("single_particle"), output_dir=None)
    sc = replace(sc, time=replace(sc.time, t_end=2e-4))
    sim = Simulation(sc)
    s = sim.run(progress=False).summary
    assert (s["factorizations"], s["jacobian_refreshes"]) == (2, 0)
    assert s["remesh_reasons"] == {"travel": 0, "angle": 0, "area": 0, "ahead": 0, "wake": 0}
    assert s["mesh"]["kind"] == "graded"
    # the poorest mesh the 20 steps ended on: the particle sinks from rest, so its mesh
    # only deforms further and the last step's mesh is the poorest; its areas against
    # the mesh as built, measured here with numpy
    from meshing.quality import signed_areas

    m = s["mesh"]
    assert m["steps_checked"] == s["steps"] == 20
    assert m["min_angle_over_steps"] == pytest.approx(m["min_angle"], rel=1e-12)
    st = sim.stepper
    t = st.mesh.t.astype(np.int64)
    built = st.keeper.reference_space.mesh.p
    ratio = (signed_areas(st.state.nodes_n, t) / signed_areas(built, t)).min()
    assert m["min_area_ratio_over_steps"] == pytest.approx(ratio, rel=1e-12)
    assert ratio < 1.0
    # a fixed mesh is the mesh as built at every step
    sc_fixed = replace(sc, mesh_motion="fixed")
    f = Simulation(sc_fixed).run(progress=False).summary["mesh"]
    assert f["steps_checked"] == 20 and f["min_area_ratio_over_steps"] == 1.0
    assert f["min_angle_over_steps"] == pytest.approx(f["min_angle"], rel=1e-12)


def test_phase_times_are_each_counted_once():
    """The summary's phases add up to at most its total, which counts the set-up (its first
    mesh and blocks, the kernels' compilation on a first run: a first single-particle run
    booked assembly 20.2 s of an 11.9 s total when the total was the loop's alone): the
    Newton refreshes inside the corrector are booked as assembly and factorisation, not
    again as solve (they were: the collapse's phases summed to 200 s of a 161 s run). The
    collapse to 20 ms has refreshes and remeshes."""
    sc = Scene.from_toml(bundled("collapse"))
    sc = replace(sc, output_dir=None, time=replace(sc.time, t_end=0.02))
    sim = Simulation(sc)
    set_up = {k: v for k, v in sim.timings.items() if k != "total"}
    assert 0 < sum(set_up.values()) <= sim.timings["total"]  # the set-up's phases, within it
    res = sim.run(progress=False)
    assert res.summary["jacobian_refreshes"] >= 1 and res.summary["remeshes"] >= 1
    phases = res.summary["wall_time"]
    assert sum(v for k, v in phases.items() if k != "total") <= phases["total"]


def test_collecting_phase_times_mid_run_loses_no_factorisation():
    """Phase times collected after every step add up to those collected once at the end:
    the factorisation cache books into the coupling's own dict, which collecting zeroes in
    place (it was replaced, and every later factorisation's time was lost)."""
    sc = replace(Scene.bundled("single_particle"), output_dir=None)
    sc = replace(sc, time=replace(sc.time, t_end=3e-4))
    sim = Simulation(sc)
    booked = 0.0
    for k, _ in enumerate(sim.evolve()):
        if k == 0:  # the BDF2-Stokes operator is factorised again at the second step
            booked = sim.stepper.collect_timings()["factorization"]
    assert sim.stepper.factor_counts["factorizations"] == 2
    assert sim.result.summary["wall_time"]["factorization"] > booked > 0.0


def test_dem_force_callbacks_act_in_coupled_runs():
    """A DEM force callback acts on a coupled run: half the immersed weight pushing up
    halves the paper's particle's velocity at every step (creeping flow, Re < 4 here: the
    particle's velocity is proportional to the net force; convection departs from it by
    3e-8). The callback used to be ignored: the velocity did not change."""
    sc = replace(Scene.bundled("single_particle"), output_dir=None)
    ref = Simulation(sc).run(progress=False).history
    sim = Simulation(sc)
    up = -0.5 * sim.stepper.weight()
    sim.dem.force_callbacks.append(lambda dem, t: (up, np.zeros(dem.n)))
    res = sim.run(progress=False).history
    assert np.abs(res.vy / ref.vy - 0.5).max() < 1e-6


def test_a_force_callback_of_the_wrong_shape_is_one_line():
    sc = replace(Scene.bundled("single_particle"), output_dir=None)
    sim = Simulation(sc)
    sim.dem.force_callbacks.append(lambda dem, t: (np.zeros(3), 0.0))
    with pytest.raises(ValueError, match=r"force_callbacks\[0\]: must return \(F, T\) of "
                                         r"shapes \(2, 1\) and \(1,\)"):
        sim.stepper.callback_forces(0.0)
