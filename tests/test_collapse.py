"""The column collapse: scene, measurements, a short dry and a short immersed release.

References. Measurements: exact values on constructed arrangements (fronts, profiles,
energies, a linear front's Froude number). Runs (the 30-grain column of
``helpers.column_packing``, released at t = 0):

- before release the fluid is at rest: total pressure = hydrostatic, i.e. the excess
  pore pressure vanishes (to 1e-6 of rho_f g H);
- energy balance: grains' (and fluid's) kinetic energy <= the potential energy released
  (buoyancy-reduced in water) plus the elastic energy stored in the contacts at rest;
- the front is never faster than the dam-break front of an inviscid fluid released
  from rest, 2 sqrt(g H0) (Ritter), so L(t) - L0 <= 2 sqrt(g H0) t;
- the excess pore pressure on the lines stays below the immersed weight of the column
  per unit area, (rho_p - rho_f) g H0;
- a looser corrector tolerance (``newton_tol`` 1e-6) changes the grains' velocities by
  less than 1 % of what halving the time step changes them by (the time step's own
  error), at fewer iterations.
"""

from dataclasses import replace

import numpy as np
import pytest
from helpers import column_packing

from skfem_granular.collapse import (
    collapse_series,
    column_scene,
    deposit_profile,
    excess_pressure,
    flowing_solid_fraction,
    front_froude,
    front_position,
    front_speed,
    front_vertex,
    history_columns,
    initial_column,
    kinetic_energies,
    line_points,
    reference_point,
)
from skfem_granular.dem import Polygon
from skfem_granular.scene import Scene
from skfem_granular.simulation import Simulation

G = 9.81


def squares(xs, y=0.0, side=1.0):
    return [Polygon.rectangle(x, y, x + side, y + side).vertices for x in xs]


def test_front_stops_at_a_gap_wider_than_a_grain():
    P = squares([0.0, 1.0, 2.5, 4.2, 7.0])  # gaps 0.5, 0.7, then 1.8 > 1
    assert front_position(P) == pytest.approx(5.2, rel=1e-15)
    assert front_position(P, gap=2.0) == pytest.approx(8.0, rel=1e-15)


def test_mass_front_counts_grains_in_contact_with_the_mass():
    """Kumar's front (2015): the farthest grain touching the main mass (the largest group
    of touching grains). Squares of side 1 touching in a row reach x = 3; a square 0.05
    ahead (a gap below one grain, so front_position counts it) does not; one touching it
    does; a diamond whose bounding box overlaps the last square but whose outline stays
    0.1 away along the diagonal does not (separating axes, not boxes); a pair of squares
    at the wall apart from a row of four is not the main mass."""
    from skfem_granular.collapse import mass_front

    row = squares([0.0, 1.0, 2.0])
    assert mass_front(row) == pytest.approx(3.0, rel=1e-15)
    ahead = row + squares([3.05])
    assert mass_front(ahead) == pytest.approx(3.0, rel=1e-15)
    assert front_position(ahead) == pytest.approx(4.05, rel=1e-15)
    bridge = ahead + squares([2.5], y=1.0)  # on the third square, touching the fourth
    assert mass_front(bridge) == pytest.approx(4.05, rel=1e-15)
    cx = 3.3  # diamond (half-diagonal 0.5) whose lower-left edge is 0.1 off (3, 1)
    cy = 4.5 + 0.1 * np.sqrt(2) - cx
    diamond = np.array([[cx, cx + 0.5, cx, cx - 0.5], [cy - 0.5, cy, cy + 0.5, cy]])
    assert front_position(row + [diamond]) > 3.0  # its box overlaps the mass
    assert mass_front(row + [diamond]) == pytest.approx(3.0, rel=1e-15)
    split = squares([0.0, 1.0]) + squares([2.2, 3.2, 4.2, 5.2])
    assert mass_front(split) == pytest.approx(6.2, rel=1e-15)


def test_profile_energies_froude_exact():
    P = squares([0.0, 2.0]) + squares([0.0], y=1.0) + [Polygon.regular(4, 1.0, (5.0, 1.0)).vertices]
    h = deposit_profile(P, [0.5, 1.5, 2.5, 4.5, 5.0, 5.25, 7.0])
    assert np.allclose(h, [2.0, 0.0, 1.0, 1.5, 2.0, 1.75, 0.0], rtol=1e-14)  # diamond at (5, 1)
    m, J = np.array([1.0, 2.0]), np.array([0.5, 0.25])
    Ex, Ey, Er = kinetic_energies(m, J, np.array([[1.0, 2.0], [3.0, 0.0]]), np.array([2.0, 2.0]))
    assert (Ex, Ey, Er) == (4.5, 4.5, 1.5)
    t = np.linspace(0.0, 0.1, 11)
    Fr = front_froude(t, 0.02 + 0.3 * t, 0.01)
    assert np.allclose(Fr, 0.3 / np.sqrt(G * 0.01), rtol=1e-12)
    lattice = [Polygon.rectangle(i + 0.1, j + 0.1, i + 0.9, j + 0.9).vertices
               for i in range(4) for j in range(3)]
    # hull of a 4 x 3 lattice of 0.8-squares: 3.8 x 2.8
    assert flowing_solid_fraction(lattice, np.ones(12), 0.5) == pytest.approx(
        12 * 0.64 / (3.8 * 2.8), rel=1e-12)
    assert np.isnan(flowing_solid_fraction(lattice, np.zeros(12), 0.5))


def test_front_speed_is_the_rate_of_the_front_and_has_no_jumps():
    """A square moving at (vx, vy) and turning at omega: its front point's speed
    equals the centred difference of L(t) (exact for the rigid motion to O(dt^2));
    a grain joining the mass moves L by a jump that dL/dt sees and the speed does not."""
    local = Polygon.rectangle(-0.5, -0.5, 0.5, 0.5).vertices
    v, w, c0 = np.array([0.3, -0.1]), 2.0, np.array([1.0, 0.5])

    def at(t):
        a = 0.2 + w * t
        R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        c = c0 + v * t
        return [R @ local + c[:, None]], c

    (P,), c = at(0.0)
    L, k, j = front_vertex([P])
    assert (k, L) == (0, P[0].max())
    U = front_speed([P], k, j, c[:, None], v[:, None], np.array([w]))
    dt = 1e-6
    dL = (front_position(at(dt)[0]) - front_position(at(-dt)[0])) / (2 * dt)
    assert U == pytest.approx(dL, rel=1e-6)
    # a second grain at rest touching the first: the front jumps, its speed is 0
    Q = Polygon.rectangle(2.4, 0.0, 3.4, 1.0).vertices
    L2, k2, j2 = front_vertex([P, Q])
    assert (k2, L2) == (1, 3.4)
    assert front_speed([P, Q], k2, j2, np.array([[1.0, 2.9], [0.5, 0.5]]),
                       np.array([[0.3, 0.0], [-0.1, 0.0]]), np.array([w, 0.0])) == 0.0
    assert front_vertex([Q], gap=0.1) == (0.0, -1, -1)  # 2.4 from the wall: no mass


def _elastic_energy(sim):
    dem = sim.dem
    _, cf = dem.evaluate(dem.particles.q, dem.particles.v, 0.0, 0.0)
    return float(cf.energy.sum())


def _released(columns, m, p0, reduced):
    """Potential energy released since t = 0 (buoyancy-reduced factor ``reduced``)."""
    y = np.asarray(columns.y)
    return reduced * G * ((p0["y"][0] - y) * m).sum(axis=1)


def test_dry_release_energy_and_front_bounds(tmp_path):
    p = column_packing("dense")
    scene = column_scene(p, fluid=False, t_end=0.04, output_dir=str(tmp_path))
    sim = Simulation(scene)
    E0 = _elastic_energy(sim)
    res = sim.run(progress=False)
    s = collapse_series(res.history, p, scene.domain)
    m = sim.dem.mass
    released = _released(res.history, m, initial_column(p, scene.domain), 1.0)
    E = s["E_x"] + s["E_y"] + s["E_rot"]
    assert np.all(E <= released + E0)
    assert released[-1] > 0.05 * m.sum() * G * p.height  # the column fell by > 5 % of H0
    assert np.all(s["front"] - p.width <= 2 * np.sqrt(G * p.height) * s["t"] + 0.05 * p.d_max)
    assert s["runout"][-1] > 0.1  # it has started to spread
    assert s["gate_height"][0] == pytest.approx(1.0, abs=0.25)
    assert np.all(s["froude"] <= 2.0)  # Ritter's front: dL/dt <= 2 sqrt(g H0)
    phi = s["flowing_fraction"][np.isfinite(s["flowing_fraction"])]
    assert phi.size and np.all((phi > 0.2) & (phi < np.pi / (2 * np.sqrt(3))))
    again = collapse_series(history_columns(tmp_path / "history.csv"), p, scene.domain)
    assert np.allclose(again["front"], s["front"], rtol=1e-12)  # from the saved run


def test_immersed_release_pressure_and_energy(tmp_path):
    p = column_packing("dense")
    tank = (3.0 * p.width, 13.0 * p.d_max)
    scene = column_scene(p, fluid=True, tank=tank, t_end=20e-3, delta_l=0.25 * p.d_mean,
                         output_dir=str(tmp_path), vtu_every=5)
    sim = Simulation(scene)
    E0 = _elastic_energy(sim)
    ref = reference_point(scene.domain, p.d_max)
    lines = np.hstack([line_points(0.5 * p.d_max, tank[0] - 0.5 * p.d_max, 10 * p.d_mean),
                       line_points(0.5 * p.d_max, tank[0] - 0.5 * p.d_max, 0.02 * p.d_mean)])
    rho_f, H = 1000.0, tank[1]
    p_scale = (p.density - rho_f) * G * p.height  # immersed weight per area of the column
    worst = 0.0
    for _t, _step in sim.evolve():
        pex = excess_pressure(sim.stepper.flow(), lines, ref)
        worst = max(worst, float(np.nanmax(np.abs(pex))))
    frame0 = sorted(tmp_path.glob("flow*/*.vtu")) or sorted(tmp_path.glob("flow_*.vtu"))
    before = excess_pressure(frame0[0], lines, ref)  # the frame at t = 0, before release
    assert np.nanmax(np.abs(before)) <= 1e-6 * rho_f * G * H
    assert 0.0 < worst < p_scale
    h = sim.history
    s = collapse_series(h, p, scene.domain)
    released = _released(h, sim.dem.mass, initial_column(p, scene.domain),
                          1.0 - rho_f / p.density)
    E = s["E_x"] + s["E_y"] + s["E_rot"] + h.fluid_energy
    assert np.all(E <= released + E0)
    assert np.all(h.fluid_energy > 0)  # the grains set the fluid moving
    assert np.all(s["front"] - p.width <= 2 * np.sqrt(G * p.height) * s["t"] + 0.05 * p.d_max)


def _grain_velocities(scene):
    """The grains' velocities after every step, and the corrector's iterations."""
    sim = Simulation(scene)
    V, iterations = [], 0
    for _t, step in sim.evolve():
        V.append(sim.dem.velocities.copy())
        iterations += step.iterations
    return np.array(V), iterations


def test_corrector_tolerance_error_is_far_below_the_time_steps():
    p = column_packing("dense")
    tank = (3.0 * p.width, 13.0 * p.d_max)
    scene = column_scene(p, fluid=True, tank=tank, t_end=4e-3, dt=2e-4,
                         delta_l=0.25 * p.d_mean)
    ref, its_ref = _grain_velocities(replace(scene, newton_tol=1e-10))
    loose, its_loose = _grain_velocities(replace(scene, newton_tol=1e-6))
    half, _ = _grain_velocities(replace(scene, newton_tol=1e-10,
                                        time=replace(scene.time, dt=1e-4)))
    assert ref.shape == loose.shape == half[1::2].shape == (20, 2, 30)
    err_tol = np.abs(loose - ref).max(axis=(1, 2))
    err_dt = np.abs(half[1::2] - ref).max(axis=(1, 2))
    assert np.all(err_tol < 0.01 * err_dt)
    assert its_loose < 0.6 * its_ref


def _scene_dict(path, **column):
    return {"domain": {"box": [0.0, 0.0, 0.02, 0.012]},
            "column": {"packing": str(path), **column},
            "effects": {"fluid": False}}


def test_toml_column_reads_the_packing_next_to_it(tmp_path):
    p = column_packing("dense")
    p.save(tmp_path / "col.npz")
    (tmp_path / "c.toml").write_text('[domain]\nbox = [0.0, 0.0, 0.02, 0.012]\n'
                                     '[column]\npacking = "col.npz"\ncore_ratio = 0.9\n'
                                     '[effects]\nfluid = false\n')
    sc = Scene.from_toml(tmp_path / "c.toml")
    assert len(sc.particles) == 30 and sc.contact_law.E == p.E
    assert {q.core_ratio for q in sc.particles} == {0.9}
    assert sc.overlap_tolerance >= p.max_overlap


@pytest.mark.parametrize("change, message", [
    ({"domain": {"box": [0.0, 0.0, 0.005, 0.012]}},
     r"column.packing: the gate at x = 0.00\d+ m .* must lie inside domain.box"),
    ({"domain": {"box": [0.0, 0.0, 0.02, 0.004]}}, "column.packing: the column reaches y ="),
    ({"contacts": {"E": 1e7}}, "contacts.E = 1e\\+07: must be the column's packing stiffness"),
    ({"column": {"core_ratio": 1.5}}, r"column.core_ratio = 1.5: must be a finite number"),
    ({"column": {"packing": "nowhere.npz"}}, "packing file .*nowhere.npz.*: not found"),
    ({"column": {"gate": 0.01}}, "column: unknown key 'gate'"),
])
def test_bad_column_one_line(tmp_path, change, message):
    path = tmp_path / "col.npz"
    column_packing("dense").save(path)
    d = _scene_dict(path)
    for k, v in change.items():
        d[k] = {**d.get(k, {}), **v}
    with pytest.raises(ValueError, match=message) as err:
        Scene.from_dict(d)
    assert "\n" not in str(err.value)


def test_realisations_give_mean_and_sample_spread():
    """Chaotic runs are reported over seeds: mean and sample standard deviation (n - 1)."""
    from skfem_granular.collapse import realisations

    r = realisations([1.0, 2.0, 4.0])
    assert r["mean"] == pytest.approx(7.0 / 3.0, rel=1e-15)
    assert r["std"] == pytest.approx(np.sqrt(((1 - 7 / 3) ** 2 + (2 - 7 / 3) ** 2
                                              + (4 - 7 / 3) ** 2) / 2), rel=1e-15)
    assert (r["min"], r["max"], r["count"]) == (1.0, 4.0, 3)
    assert realisations([5.0])["std"] is None
    with pytest.raises(ValueError, match="one value per realisation"):
        realisations([])


def test_dry_laws_published_coefficients():
    """The laws as published: Lajeunesse et al. 2005 (quasi-2D channel) 1.2 a below
    a = 2.3 and 1.9 a^(2/3) above; Kumar 2015 (2D DEM) 1.67 a below 2.7, 2.7 a^(2/3)
    above; Zenit 2005 1.43 a^0.65; Staron & Hinch 1.3 a continued as a^(2/3) above 3."""
    from skfem_granular.collapse import DRY_LAWS, dry_runout

    a = np.array([0.5, 2.0, 2.5, 4.0])
    assert np.allclose(dry_runout(a), [0.6, 2.4, 1.9 * 2.5 ** (2 / 3), 1.9 * 4 ** (2 / 3)],
                       rtol=1e-15)
    assert np.allclose(dry_runout(a, "Kumar 2015 (2D DEM)"),
                       [0.835, 3.34, 4.175, 2.7 * 4 ** (2 / 3)], rtol=1e-15)
    assert dry_runout(1.0, "Zenit 2005") == pytest.approx(1.43, rel=1e-15)
    sh = dry_runout(np.array([3.0 - 1e-9, 3.0]), "Staron & Hinch 2005")
    assert sh[1] == pytest.approx(sh[0], rel=1e-8)  # continuous at a = 3
    assert set(DRY_LAWS) >= {"Lajeunesse et al. 2005", "Kumar 2015 (2D DEM)"}
    with pytest.raises(ValueError, match="law = 'Lube'"):
        dry_runout(1.0, "Lube")
    with pytest.raises(ValueError, match="aspect ratio H0 / L0 must be finite and > 0"):
        dry_runout(-1.0)


def test_runout_curves_plot_the_series_in_the_given_styles(tmp_path):
    """Each curve is drawn from its own series, in its style if one is given."""
    pytest.importorskip("matplotlib")
    from skfem_granular.collapse.plots import plot_runout_curves

    t = np.linspace(0.0, 8.0, 9)
    curves = {"dense": (t, 0.1 * t), "loose": (t, 0.2 * t)}
    ax = plot_runout_curves(curves, styles={"loose": "C1:"})
    dense, loose = ax.get_lines()
    np.testing.assert_array_equal(loose.get_ydata(), 0.2 * t)
    from matplotlib.colors import same_color

    assert loose.get_linestyle() == ":" and same_color(loose.get_color(), "C1")
    assert dense.get_linestyle() == "-"
    path = tmp_path / "runout.png"
    plot_runout_curves(curves, path)
    assert path.stat().st_size > 0
