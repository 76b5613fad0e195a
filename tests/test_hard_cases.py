"""Hard cases stay stable: large steps, remeshing energy, light particles."""

from dataclasses import replace

import numpy as np
import pytest

from skfem_granular.scene import Effects, Scene, TimeSpec, bundled
from skfem_granular.simulation import Simulation

SCENES = bundled("single_particle").parent  # the bundled scenes (skfem_granular/scene/library)


@pytest.fixture(scope="module")
def paper():
    """The paper's single particle, writing no files (several runs per test)."""
    return replace(Scene.from_toml(SCENES / "single_particle.toml"), output_dir=None)


def _total_energy(sim, h):
    m, inertia = sim.dem.mass[0], sim.dem.inertia[0]
    return (h.fluid_energy + 0.5 * m * (h.vx[:, 0] ** 2 + h.vy[:, 0] ** 2)
            + 0.5 * inertia * h.omega[:, 0] ** 2)


@pytest.mark.parametrize("factor", [1, 10, 100])
def test_large_steps_decay_energy(paper, factor):
    """A particle launched at 1 cm/s without gravity: BDF2 (L-stable) only loses energy.

    dt = 1e-5 s (the scene's), 10x and 100x larger over 5 ms: the kinetic energy of
    fluid + particle never grows from one step to the next, and all three step sizes
    end at the same energy (0.5024 of the launch energy, measured).
    """
    p = replace(paper.particles[0], velocity=(0.0, -0.01))
    dt = 1e-5 * factor
    sc = replace(paper, particles=(p,), time=TimeSpec(t_end=5e-3, dt=dt),
                 effects=Effects(gravity=False))
    sim = Simulation(sc)
    h = sim.run(progress=False).history
    E = _total_energy(sim, h)
    E0 = 0.5 * sim.dem.mass[0] * 0.01**2
    assert np.all(np.isfinite(E)) and E[0] < E0
    assert np.all(np.diff(E) <= 1e-12 * E[:-1])
    assert E[-1] / E0 == pytest.approx(0.5024, abs=0.002)


@pytest.mark.parametrize("motion", ["fixed", "ale"])
def test_remeshing_creates_no_energy(paper, motion):
    """Both BDF2 histories move to each new mesh; interpolation may not add energy.

    The total energy keeps falling across every remesh; one interpolation onto a
    rebuilt graded mesh changes the fluid's energy by at most 2 % (interpolation
    error of the P2 field, measured +1.05 % at worst).
    """
    p = replace(paper.particles[0], velocity=(0.0, -0.05))
    sc = replace(paper, particles=(p,), time=TimeSpec(t_end=2e-3, dt=1e-4),
                 effects=Effects(gravity=False), remesh_fraction=0.1, mesh_motion=motion,
                 remesh_travel=0.05)
    sim = Simulation(sc)
    h = sim.run(progress=False).history
    assert sim.remeshes >= 2
    E = _total_energy(sim, h)
    assert np.all(np.diff(E) < 0)
    assert max(sim.remesh_energy_ratios) < 1.02


def test_light_particle_rises_bounded(paper):
    """rho_p / rho_f = 0.5 and 0.1: the monolithic coupling stays bounded and rises."""
    for ratio in (0.5, 0.1):
        p = replace(paper.particles[0], density=1000.0 * ratio)
        sc = replace(paper, particles=(p,), time=TimeSpec(t_end=1e-3, dt=1e-4))
        h = Simulation(sc).run(progress=False).history
        assert np.all(np.isfinite(h.vy)) and np.all(h.vy[:, 0] > 0)
        assert np.all(np.diff(h.vy[:, 0]) > 0)  # still accelerating upwards at 1 ms
        # bounded by the free (fluid-less) buoyant acceleration times t
        assert h.vy[-1, 0] < 9.81 * (1 / ratio - 1) * 1e-3


def test_neutrally_buoyant_particle(paper):
    """rho_p / rho_f = 1.001: a tiny, steady sinking without wiggles."""
    p = replace(paper.particles[0], density=1001.0)
    h = Simulation(replace(paper, particles=(p,), time=TimeSpec(t_end=5e-4, dt=1e-5))
                   ).run(progress=False).history
    vy = h.vy[:, 0]
    assert np.all(vy < 0) and np.all(np.diff(vy) < 0)
    # first-step acceleration below the added-mass limit of an unbounded fluid
    limit = 9.81 * 0.001 / (1.001 + 1.0)
    assert 0 < -h.ay[0, 0] < limit


@pytest.mark.slow
def test_hundred_grains_remeshing_conserves_mass_volume_count():
    """10 x 10 hexagons with a remesh after (nearly) every step.

    Across every remesh: particle count and total particle mass unchanged, the
    fluid area equal to the box minus the cores to round-off, no energy created
    by the transfer beyond the stated 2 %.
    """
    data = {"domain": {"box": [0.0, 0.0, 14e-3, 14e-3]},
            "fluid": {"density": 1000.0, "viscosity": 1e-3},
            "grid": {"nx": 10, "ny": 10, "sides": 6, "radius": 0.5e-3, "spacing": 1.15e-3,
                     "origin": [1.5e-3, 2.0e-3], "density": 2650.0, "core_ratio": 0.8,
                     "jitter": 0.3},
            "mesh": {"kind": "group", "delta_l": 0.25e-3},
            "time": {"t_end": 6e-3, "dt": 2e-4},
            "coupling": {"remesh_fraction": 0.005, "remesh_travel": 0.005}}
    sim = Simulation(Scene.from_dict(data, name="hundred"))
    mass0 = sim.dem.mass.sum()
    h = sim.run(progress=False).history
    assert sim.dem.n == 100 and sim.remeshes >= 5
    assert sim.dem.mass.sum() == mass0
    cores = sim.dem.core_outlines()
    area = 14e-3 ** 2 - sum(0.5 * np.sum(c[0] * np.roll(c[1], -1) - np.roll(c[0], -1) * c[1])
                            for c in cores)
    assert sim.space.ub.dx.sum() == pytest.approx(area, rel=1e-12)
    assert max(sim.remesh_energy_ratios) < 1.02
    assert np.all(np.isfinite(h.vy))


@pytest.mark.slow
def test_resting_grain_long_run_no_drift_no_energy_creation():
    """A hexagon resting on the floor, 1e4 coupled steps (1 s) with contacts.

    Measured (backward Euler at contacts, 61 s): x drift 1.2e-10 m, height within
    6e-16 m after the first 10 % of the run, speed below 1.2e-13 m/s there, kinetic
    energy of fluid + grain 1.1e-16 J/m at 5-10 % of the run and 1.6e-20 J/m at most
    in the second half. (With BDF2 throughout the grain rattled at the contact: 8e-5
    m/s, 1.25e-10 J/m, a 77 nm band.)
    """
    data = {"domain": {"box": [0.0, 0.0, 4e-3, 3e-3]},
            "fluid": {"density": 1000.0, "viscosity": 1e-3},
            "particles": [{"sides": 6, "radius": 0.5e-3, "center": [2e-3, 0.4331e-3],
                           "density": 2650.0, "core_ratio": 0.8}],
            "mesh": {"kind": "graded", "delta_l": 0.15e-3},
            "time": {"t_end": 1.0, "dt": 1e-4},
            "effects": {"contacts": True}}
    sim = Simulation(Scene.from_dict(data, name="rest"))
    h = sim.run(progress=False).history
    n = len(h)
    assert n == 10000 and sim.retries == 0
    assert np.abs(h.x[:, 0] - 2e-3).max() < 1e-9
    settled = slice(n // 10, None)
    assert np.ptp(h.y[settled, 0]) < 1e-12
    assert np.abs(np.stack([h.vx[settled, 0], h.vy[settled, 0]])).max() < 1e-9
    KE = _total_energy(sim, h)
    assert KE[n // 2:].max() <= KE[n // 20: n // 10].max() < 1e-14  # no energy creation
    assert np.all(h.contacts[settled, 0] >= 1)  # it stays on the floor


def test_wake_at_reynolds_100_adaptive_steps_keep_the_error_below_tolerance():
    """A cylinder started impulsively at Re = U d / nu = 100 in a closed channel.

    Adaptive BDF2 (fluid.evolve): every accepted step has its Milne estimate below
    the tolerance; steps are rejected and retried around the impulsive start and
    grow by orders of magnitude afterwards; the chord iteration converges (on a refreshed
    Newton Jacobian where it stalls).
    Measured to t = 3: 79 steps, 8 rejections, error <= 9.6e-4 (tol 1e-3), dt from
    2e-6 to 0.2.
    """
    import meshing
    import skfem_granular as sg

    disk = sg.Polygon.regular(48, 0.5, center=(0.0, 0.0))
    mesh = meshing.graded_mesh((-4.0, -2.0, 12.0, 2.0), [disk.vertices], sigma=1.15)
    bc = {"wall": (0.0, 0.0), "particle0": (-1.0, 0.0)}
    tol = 1e-3
    steps, flow = [], None
    for _, flow in sg.evolve(mesh, sg.Fluid(1.0, 0.01), bc, dt=1e-3, t_end=1.5, adaptive=True,
                             tol=tol):
        steps.append(flow.step)
    errors = [s.error for s in steps if s.error is not None]
    assert max(errors) <= tol
    assert sum(s.rejected for s in steps) >= 1
    dts = np.array([s.dt for s in steps])
    assert dts.max() > 1e3 * dts.min()
    assert np.all(dts[1:] / dts[:-1] <= 2.0 + 1e-12)
    # the fluid pushes back against the motion (-x): drag along +x, no lift by symmetry
    F = flow.force("particle0")
    assert F[0] > 0 and abs(F[1]) < 1e-3 * F[0]


def _hexagons(particles, box, t_end, dt, motion="auto", **time):
    return Scene.from_dict({
        "coupling": {"mesh_motion": motion, "remesh_travel": 0.05},
        "domain": {"box": box}, "fluid": {"density": 1000.0, "viscosity": 1e-3},
        "particles": [dict(sides=6, radius=0.5e-3, density=2650.0, core_ratio=0.8, **p)
                      for p in particles],
        "mesh": {"kind": "graded", "delta_l": 0.1e-3},
        "time": dict(t_end=t_end, dt=dt, **time),
        "effects": {"contacts": True, "gravity": False}}, name="approach")


def _run_watching_meshes(sim):
    """Run; the inverted-element count and smallest element area of every mesh used."""
    import meshing

    seen = []
    for _ in sim.evolve():  # the mesh each accepted step was computed on
        st = meshing.mesh_stats(sim.mesh)
        seen.append((st.n_inverted, float(sim.space.ub.dx.sum(axis=1).min())))
    return sim.result.history, np.array(seen)


def _energy(sim, h):
    m, inertia = sim.dem.mass, sim.dem.inertia
    return h.fluid_energy + (0.5 * m * (h.vx ** 2 + h.vy ** 2) + 0.5 * inertia * h.omega ** 2
                             ).sum(axis=1)


def _bounce(h, E):
    """Steps just before the first contact and just after the last; energy ratio."""
    touching = h.contacts.max(axis=1) >= 1
    first = int(np.argmax(touching))
    last = len(touching) - 1 - int(np.argmax(touching[::-1]))
    return first, last, E[last + 1] / E[first - 1]


@pytest.mark.parametrize("motion", ["fixed", "ale"])
def test_particle_driven_into_the_floor_bounces_without_creating_energy(motion):
    """A hexagon launched at 5 cm/s towards the floor, adaptive steps (tol 1e-3).

    The shadow (contact outline) touches the floor while the core (fluid boundary)
    is 0.087 mm above it: contact force takes over, the grain comes back. Measured:
    energy of grain + fluid after / before the bounce 0.76, 228 steps with 18
    rejections, every mesh valid.
    """
    sim = Simulation(_hexagons([{"center": [2e-3, 0.5e-3], "velocity": [0.0, -0.05]}],
                               [0.0, 0.0, 4e-3, 3e-3], 3e-3, 2e-5, motion, adaptive=True,
                               tol=1e-3))
    h, meshes = _run_watching_meshes(sim)
    assert h.t[-1] == pytest.approx(3e-3, rel=1e-9) and sim.retries == 0
    assert sim.remeshes >= 2 and meshes[:, 0].max() == 0 and meshes[:, 1].min() > 0
    first, last, ratio = _bounce(h, _energy(sim, h))
    assert 0 < first < last  # the shadows touched
    assert h.vy[first - 1, 0] < -0.02 and h.vy[-1, 0] > 0.015  # it came back
    assert ratio < 1.0
    assert np.nanmax(h.error) <= 1e-3 and sim.rejections > 0
    assert sim.dem.core_outlines()[0][1].min() > 0  # the core never reached the floor


@pytest.mark.parametrize("dt", [2e-5, 5e-6])
def test_fixed_steps_at_a_contact_do_not_create_energy(dt):
    """The same launch at fixed steps. Backward Euler on contact steps: energy ratios
    0.68 (20 us), 0.74 (10 us), 0.76 (5 us), approaching the adaptive run's 0.76 from
    below. (With BDF2 throughout they were 1.37, 1.16, 0.98: energy created.)"""
    sim = Simulation(_hexagons([{"center": [2e-3, 0.5e-3], "velocity": [0.0, -0.05]}],
                               [0.0, 0.0, 4e-3, 3e-3], 3e-3, dt))
    h = sim.run(progress=False).history
    first, last, ratio = _bounce(h, _energy(sim, h))
    assert ratio < 0.8
    assert sim.euler_steps >= last - first + 1  # every contact step, and the two after
    E = _energy(sim, h)
    # once the contact is over (its spring energy given back), the energy only falls: with
    # BDF2 throughout it kept rising for 2-3 steps
    assert np.all(np.diff(E[last + 1: last + 8]) <= 0)


def test_steps_too_long_for_contacts_are_warned_about():
    launch = [{"center": [2e-3, 0.5e-3], "velocity": [0.0, -0.05]}]
    box = [0.0, 0.0, 4e-3, 3e-3]
    fixed = Simulation(_hexagons(launch, box, 3e-3, 2e-5))
    assert any("time.dt = 2e-05 s does not resolve a contact" in w for w in fixed.warnings)
    resolved = Simulation(_hexagons(launch, box, 3e-3, 5e-6))
    assert not any("does not resolve a contact" in w for w in resolved.warnings)
    adaptive = Simulation(_hexagons(launch, box, 3e-3, 2e-5, adaptive=True))
    assert not any("does not resolve a contact" in w for w in adaptive.warnings)
    on_purpose = Simulation(_hexagons(launch, box, 3e-3, 2e-5, contact_warning=False))
    assert not any("does not resolve a contact" in w for w in on_purpose.warnings)


def _head_on_pair(motion, delta_l=0.1e-3, travel=0.05):
    parts = [{"center": [2.3e-3, 1.5e-3], "velocity": [0.05, 0.0], "angle": np.pi / 6},
             {"center": [3.7e-3, 1.5e-3], "velocity": [-0.05, 0.0], "angle": np.pi / 6}]
    scene = _hexagons(parts, [0.0, 0.0, 6e-3, 3e-3], 0.012, 2e-5, motion)
    # the paper's circles throughout: the grains start at Re 40.0 (d = 0.8 mm cores at
    # 5 cm/s), the wake rule's threshold, where round-off decides whether it remeshes
    return Simulation(replace(scene, remesh_travel=travel,
                              mesh=replace(scene.mesh, delta_l=delta_l, wake=False)))


def _pair_momentum(h):
    """The pair's horizontal momentum at the end, relative to one grain's."""
    return abs(h.vx[-1].sum()) / abs(h.vx[-1, 0])


@pytest.mark.parametrize("motion, travel", [("fixed", 0.05), ("ale", 1.0)])
def test_two_particles_collide_head_on_and_separate(motion, travel):
    """Two hexagons approaching each other at 5 cm/s each until their shadows touch.

    Measured (delta_l = 0.1 mm): contact at 8.7 ms, they separate at 1.2 cm/s (energy of
    grains + fluid after / before 0.49), no inverted element on any mesh. The pair's
    horizontal momentum at the end, relative to one grain's, is discretisation error of
    the unsymmetric mesh: moving mesh at its default remesh rule (1 remesh) 1.6e-4.
    Remeshing the moving mesh every 0.05 radii (15 remeshes) gives 9.6e-4: each transfer
    onto a new unsymmetric mesh adds an asymmetric interpolation error, which converges
    with the mesh (:func:`test_head_on_pair_momentum_converges_with_the_mesh`). On the
    fixed mesh (remesh every 0.05 radii, 11 remeshes) that error depends on round-off:
    a mesh built for outlines 1e-17 m apart can differ (the histories part at the third
    remesh), and starting the first grain 1e-15 / 3e-15 / 1e-14 m further right gave
    6.7e-4 / 6.7e-4 / 6.1e-5 (and 1.0e-4 unperturbed with the numpy convection of
    4e84a43): hence the bound 1e-3 there.
    """
    sim = _head_on_pair(motion, travel=travel)
    h, meshes = _run_watching_meshes(sim)
    assert len(h) == 600 and meshes[:, 0].max() == 0 and meshes[:, 1].min() > 0
    assert sim.remeshes >= 1
    first, last, ratio = _bounce(h, _energy(sim, h))
    assert 0 < first < last < len(h) - 1
    assert h.vx[-1, 0] < -0.005 and h.vx[-1, 1] > 0.005  # they move apart
    assert _pair_momentum(h) < (1e-3 if motion == "fixed" else 3e-4)
    assert ratio < 1.0
    gap = sim.dem.core_outlines()[1][0].min() - sim.dem.core_outlines()[0][0].max()
    assert gap > 0  # cores never overlapped


@pytest.mark.slow
def test_head_on_pair_momentum_converges_with_the_mesh():
    """The moving mesh remeshed every 0.05 radii (the transfers' worst case): the pair's
    momentum error falls with the mesh. Measured: 9.6e-4 (delta_l 0.1 mm, 15 remeshes),
    5.7e-5 (0.05 mm, 14 remeshes), a factor of 17; the fixed mesh 8.7e-5 and 2.5e-5."""
    coarse = _pair_momentum(_head_on_pair("ale").run(progress=False).history)
    fine = _pair_momentum(_head_on_pair("ale", delta_l=0.05e-3).run(progress=False).history)
    assert coarse < 2e-3 and fine < coarse / 8


@pytest.mark.parametrize("motion", ["fixed", "ale"])
def test_particle_at_reynolds_100_adaptive_coupled_steps(motion):
    """A 24-gon (d = 1 mm) launched at 10 cm/s in water (Re = 100), no gravity, adaptive
    coupled BDF2 with remeshing, first step 0.2 ms (far too large for the start).

    Measured: 87 steps and 42 rejections over 5 ms, steps 3.5e-7 ... 2e-4 s, every
    accepted estimate below tol, the grain slows from 6.9 to 5.9 cm/s, energy of
    grain + fluid falls from 7.0e-6 to 5.7e-6 J/m (single steps gain at most 5e-4
    of it, at remeshes), no retries.
    """
    data = {"domain": {"box": [0.0, 0.0, 16e-3, 6e-3]},
            "fluid": {"density": 1000.0, "viscosity": 1e-3},
            "particles": [{"sides": 24, "radius": 0.5e-3, "center": [4e-3, 3e-3],
                           "density": 2650.0, "velocity": [0.1, 0.0]}],
            # the paper's circles: with the wake rule (Re 100) the run remeshes at t = 0 and
            # then every 4-5 steps, so that the step control, which skips the first four
            # steps on a new mesh, made 2 estimates in 25 steps of 0.2 ms (final speed within
            # 5e-5 of this run's; docs/meshing.md)
            "mesh": {"kind": "graded", "delta_l": 0.13e-3, "wake": False},
            "time": {"t_end": 5e-3, "dt": 2e-4, "adaptive": True, "tol": 1e-3},
            "effects": {"gravity": False},
            "coupling": {"mesh_motion": motion, "remesh_travel": 0.1}}
    sim = Simulation(Scene.from_dict(data, name="wake"))
    h = sim.run(progress=False).history
    assert h.t[-1] == pytest.approx(5e-3, rel=1e-9) and sim.retries == 0
    assert np.nanmax(h.error) <= 1e-3 and np.isfinite(h.error).sum() > len(h) // 3
    assert sim.rejections > 0 and h.dt.max() / h.dt.min() > 100 and sim.remeshes >= 3
    E = _energy(sim, h)
    assert E[-1] < 0.9 * E[0] and np.max(np.diff(E) / E[:-1]) < 2e-3
    assert 0.05 < h.vx[-1, 0] < h.vx[1, 0]  # slowed by drag, still moving
    assert abs(h.vy[:, 0]).max() < 1e-6 * h.vx[0, 0]  # the wake has not turned it yet


def test_dem_substeps_skipped_where_no_contact_can_start(monkeypatch):
    """The bundled settling disk (contacts on, 1 ms steps) for 0.1 s, far from the walls:
    no contact can start within a step, so the DEM is not subcycled (0 DEM steps; 4100
    substeps when it is forced to run every step) and the coupled BDF2 poses are used.
    Measured over these 0.1 s: heights agree to 6.9e-5 of the distance fallen and
    velocities to 6.4e-6 of the largest speed (step-error level; 3.0e-5 and 7.2e-6 over
    0.2 s), wall time 1.5 s against 2.8 s."""
    import skfem_granular.dem.system as dem_system

    def run():
        scene = replace(Scene.bundled("settling_disk_channel"), output_dir=None)
        sim = Simulation(replace(scene, time=replace(scene.time, t_end=0.1)))
        return sim, sim.run(progress=False).history

    skipped, h = run()
    assert skipped.stepper.contacts_active and skipped.dem.steps == 0
    monkeypatch.setattr(dem_system.DEMSystem, "contact_possible",
                        lambda self, dt, acceleration=0.0: True)
    forced, g = run()
    assert forced.dem.steps > 1000
    fallen = abs(g.y[-1, 0] - g.y[0, 0])
    assert np.abs(h.y - g.y).max() < 1e-4 * fallen
    assert np.abs(h.vy - g.vy).max() < 1e-5 * np.abs(g.vy).max()


def test_a_step_that_would_invert_the_moving_mesh_is_halved(monkeypatch):
    """A hexagon shot at the floor at 0.3 m/s with a 2 ms step and no contacts: the
    corrector's first iterates move it 0.6 mm, through the 0.55 mm gap, which would invert
    triangles. That step fails like an unconverged one and is halved (measured: 1 halving,
    two 1 ms steps, one remesh) instead of stopping the run with an error; no block is ever
    assembled on an inverted triangle."""
    from skfem_granular.fluid.space import TaylorHood

    refused = []
    moved = TaylorHood.moved

    def watched(self, p):
        try:
            return moved(self, p)
        except ValueError:
            refused.append(p)
            raise

    monkeypatch.setattr(TaylorHood, "moved", watched)
    scene = _hexagons([{"center": [2e-3, 0.9e-3], "velocity": [0.0, -0.3]}],
                      [0.0, 0.0, 4e-3, 3e-3], 2e-3, 2e-3, "ale")
    sim = Simulation(replace(scene, effects=replace(scene.effects, contacts=False)))
    h, meshes = _run_watching_meshes(sim)
    assert refused and sim.retries >= 1
    assert h.t[-1] == pytest.approx(2e-3) and h.dt.max() < 2e-3
    assert meshes[:, 0].max() == 0 and meshes[:, 1].min() > 0
    assert 0 < h.y[-1, 0] < 0.9e-3
