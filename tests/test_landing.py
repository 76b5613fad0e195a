"""A particle reaching the floor: without contacts the run stops with one line naming
the fix (after a remesh was tried, before the steps shrink to nothing); with contacts
and a core smaller than the shadow it lands and comes to rest."""

import numpy as np
import pytest

from skfem_granular.coupled.landing import LANDING_GAP, core_gaps, landed, landing_message
from skfem_granular.scene import Scene
from skfem_granular.simulation import Simulation, SimulationError


def square(c, half):
    x, y = c
    return np.array([[x - half, x + half, x + half, x - half],
                     [y - half, y - half, y + half, y + half]])


def test_core_gaps_walls_and_neighbours():
    """Squares at known distances: 0.1 to the floor, 0.05 between two of them."""
    cores = [square((1.0, 0.6), 0.5), square((2.5, 0.8), 0.5), square((2.0, 3.4), 0.5)]
    gaps, partner = core_gaps(cores, (0.0, 0.0, 4.0, 5.0))
    np.testing.assert_allclose(gaps, [0.1, 0.3, 1.1], rtol=1e-12)
    assert list(partner) == [-1, -1, -3]          # bottom (edge 0), bottom, top (edge 2)
    cores[1] = square((2.05, 1.0), 0.5)          # 0.05 from square 0
    gaps, partner = core_gaps(cores, (0.0, 0.0, 4.0, 5.0))
    np.testing.assert_allclose(gaps, [0.05, 0.05, 1.1], rtol=1e-9)
    assert list(partner) == [1, 0, -3]
    # a rotated square, a corner towards its neighbour's edge
    d = np.sqrt(0.5)
    diamond = np.array([[2.3 + d, 2.3, 2.3 - d, 2.3], [3.0, 3.0 + d, 3.0, 3.0 - d]])
    gaps, partner = core_gaps([square((1.0, 3.0), 0.5), diamond], (0.0, 0.0, 4.0, 5.0))
    np.testing.assert_allclose(gaps, [2.3 - d - 1.5] * 2, rtol=1e-12)
    assert list(partner) == [1, 0]
    assert landed(np.array([0.1, 0.004]), np.array([1.0, 0.1])) == 1
    assert landed(np.array([0.1, 0.006]), np.array([1.0, 0.1])) is None


def test_landing_message_is_one_line_with_the_fix():
    names = ("bottom", "right", "top", "left")
    m = landing_message(0, 5.6e-7, -1, 1.3e-4, names, False, True, 0.0121)
    assert "\n" not in m and "particle 0 reached the bottom wall" in m
    assert "[effects] contacts = true" in m and "core_ratio" in m
    m = landing_message(1, 5.6e-7, 0, 1.3e-4, names, True, True, 0.0121)
    assert "reached particle 0" in m and "core_ratio below 1" in m
    assert "[effects]" not in m


def _disk(contacts, center_y, dt, t_end, **particle):
    return Scene.from_dict({
        "domain": {"box": [0.0, 0.0, 3e-3, 3e-3]},
        "fluid": {"density": 1000.0, "viscosity": 1e-3},
        "particles": [dict(sides=24, radius=0.5e-3, center=[1.5e-3, center_y],
                           density=2650.0, **particle)],
        "mesh": {"kind": "graded"},
        "time": {"t_end": t_end, "dt": dt},
        "effects": {"contacts": contacts}}, name="landing")


def test_landing_without_contacts_stops_with_the_fix():
    """24-gon, 2650 kg/m^3, in water, 0.2 mm above the floor, steps of 2 ms, no contacts.

    Before: remeshed at every step below a gap of 0.02 outline edges, the steps fell to
    1e-6 s, then "mesh motion: triangle 104 is inverted" at t = 0.0121562 s (after 4
    halvings down to 1.2e-7 s). Now: stopped at t = 0.012125 s (gap 0.56 um, 0.004 edges),
    one landing remesh tried (6 remeshes in all), the smallest step 1.25e-4 s.
    """
    sim = Simulation(_disk(False, 0.7e-3, 2e-3, 0.05))
    with pytest.raises(SimulationError) as err:
        sim.run(progress=False)
    msg = str(err.value)
    assert "\n" not in msg
    assert "particle 0 reached the bottom wall" in msg
    assert "enable contacts ([effects] contacts = true)" in msg
    h = sim.history
    edge = 2 * 0.5e-3 * np.sin(np.pi / 24)
    gap = h.y[-1, 0] - 0.5e-3     # a vertex points at the floor
    assert 0.0 < gap < LANDING_GAP * edge
    assert sim.remeshes >= 1
    assert np.min(h.dt) >= 2e-3 / 16  # never more than 4 halvings
    # it got there falling: about the time of a fall of 0.2 mm at the measured speeds
    assert 0.01 < h.t[-1] < 0.013


def test_landing_with_contacts_comes_to_rest():
    """The same disk, an edge down, core 0.9 of the shadow, contacts: lands and rests.

    The fluid's force then vanishes and the contact carries the immersed weight.
    Measured: first contact at 6 ms; over the last 5 steps |v| <= 5.3e-7 m/s at 70 ms,
    the shadow 0.02 um into the floor, fluid force 1.1e-4 of the immersed weight.
    """
    sim = Simulation(_disk(True, 0.56e-3, 1e-3, 0.07, angle=np.pi / 24, core_ratio=0.9))
    res = sim.run(progress=False)
    h = res.history
    assert h.contacts[-1, 0] >= 1
    speed = np.hypot(h.vx[-5:, 0], h.vy[-5:, 0])
    assert speed.max() < 1e-6
    core_gap = sim.dem.core_outlines()[0][1].min()
    overlap = 0.05e-3 * np.cos(np.pi / 24) - core_gap   # of the shadow into the floor
    assert 0.0 < overlap < 1e-6
    weight = (2650.0 - 1000.0) * 9.81 * 12 * (0.5e-3) ** 2 * np.sin(2 * np.pi / 24)
    assert abs(h.Fy[-1, 0]) < 1e-3 * weight


def test_core_gaps_cutoff_is_exact_below_it():
    """Random hexagons in a box: with a cutoff, every gap below it equals the exact gap
    (same partner), every other one is at or above it."""
    rng = np.random.default_rng(3)
    ang = np.linspace(0, 2 * np.pi, 7)[:-1]
    centres = [(x, y) for x in np.arange(0.6, 9.5, 1.05) for y in np.arange(0.6, 5.5, 1.05)]
    cores = [np.array([cx + 0.5 * np.cos(ang + t), cy + 0.5 * np.sin(ang + t)])
             for (cx, cy), t in zip(centres, rng.uniform(0, np.pi, len(centres)), strict=True)]
    box = (0.0, 0.0, 10.0, 6.0)
    exact, p_exact = core_gaps(cores, box)
    cut = np.full(len(cores), 0.12)
    gaps, partner = core_gaps(cores, box, cutoff=cut)
    below = exact < cut
    assert 0 < below.sum() < len(cores)
    np.testing.assert_array_equal(gaps[below], exact[below])
    np.testing.assert_array_equal(partner[below], p_exact[below])
    assert np.all(gaps[~below] >= cut[~below])
    # brute force over every pair
    from meshing.geometry import edge_distance
    for k, P in enumerate(cores):
        walls = edge_distance(np.array([[0.0, 10.0, 10.0, 0.0], [0.0, 0.0, 6.0, 6.0]]),
                              P)[0].min()
        pairs = [min(-edge_distance(Q, P)[0].max(), -edge_distance(P, Q)[0].max())
                 for j, Q in enumerate(cores) if j != k]
        assert exact[k] == pytest.approx(min(walls, *pairs), rel=1e-12)
