"""Rolling resistance against its model: stopping distance, energy balance, rest.

A near-disk (a 64-gon, apothem ``a``) rolling without slip on a floor meets the full
mobilisation torque ``M_m = mu_r a m g`` once its rolling spring has wound up, so its
kinetic energy ``(m + I / a^2) v^2 / 2`` falls by ``mu_r m g`` per unit distance: it
stops after ``d = (1 + I / (m a^2)) v0^2 / (2 mu_r g)`` (the spring's wind-up and the
polygon's corners change this by well under a per cent; without rolling resistance the
same grain keeps 98.6 % of its energy over 27 times that distance).
"""

import numpy as np
import pytest

from skfem_granular.dem import ContactLaw, DEMSystem, Particle, Polygon, overlap_numba
from skfem_granular.scene import Scene

R = 0.5e-3
G = 9.81
FLOOR = Polygon(np.array([[0.0, 0.05, 0.05, 0.0], [-1e-3, -1e-3, 0.0, 0.0]]))


def rolling_grain(law, sides=64, v0=0.02, backend="auto"):
    """A ``sides``-gon on the floor, rolling to the right at ``v0`` without slip."""
    a = R * np.cos(np.pi / sides)
    lowest = Polygon.regular(sides, R).vertices[1].min()
    grain = Particle(Polygon.regular(sides, R, center=(2e-3, -lowest - 1e-7)), 2650.0,
                     velocity=(v0, 0.0), angular_velocity=-v0 / a)
    return DEMSystem([grain], [FLOOR], law=law, backend=backend), a


def roll_to_rest(s, t_max):
    while s.t < t_max:
        s.advance(1e-3)
        if np.hypot(*s.velocities[:, 0]) < 1e-6 and abs(s.angular_velocities[0]) * R < 1e-6:
            return True
    return False


@pytest.mark.parametrize("mu_r", [0.05, 0.2])
def test_a_rolling_grain_stops_where_the_model_predicts(mu_r):
    v0 = 0.02
    s, a = rolling_grain(ContactLaw(E=1e7, mu=0.8, gamma=0.3, mu_r=mu_r), v0=v0)
    x0 = s.positions[0, 0]
    m, inertia = s.mass[0], s.inertia[0]
    predicted = (1.0 + inertia / (m * a * a)) * v0**2 / (2.0 * mu_r * G)
    assert roll_to_rest(s, 0.5)
    # measured: 1.0050 (mu_r 0.05), 0.9935 (0.2)
    assert (s.positions[0, 0] - x0) / predicted == pytest.approx(1.0, abs=0.015)


def test_without_rolling_resistance_the_grain_rolls_on():
    v0 = 0.02
    s, _ = rolling_grain(ContactLaw(E=1e7, mu=0.8, gamma=0.3), v0=v0)
    E0 = s.kinetic_energy()
    s.advance(0.2)
    assert s.contacts.mr is None and "contact_mr" not in s.save_state()
    assert s.kinetic_energy() > 0.98 * E0  # measured 0.993 after 4 mm
    assert s.velocities[0, 0] > 0.99 * v0


def test_the_energy_lost_is_the_work_of_the_rolling_torque():
    """Elastic normal and tangential contacts, no slip: kinetic, potential and elastic
    energy (the rolling spring's included) fall by the work of the rolling torques."""
    law = ContactLaw(E=1e7, mu=0.8, gamma=0.0, gamma_t=0.0, mu_r=0.1, eta_r=0.3)
    s, a = rolling_grain(law, backend="numpy")
    rest, _ = rolling_grain(ContactLaw(E=1e7, mu=0.8, gamma=0.5), v0=0.0, backend="numpy")
    for _ in range(3000):  # settled on the floor first: no bounce
        rest.step()
    s.particles.q[...] = rest.particles.q
    s.reset_history()
    s.step(s.dt)

    def energy():
        return s.kinetic_energy() + s.mass[0] * G * s.positions[1, 0] + s.elastic_energy()

    E0, work = energy(), 0.0
    while s.t < 0.03:
        w_old = s.angular_velocities[0]
        s.step(s.dt)
        work += s.contacts.mr[0] * 0.5 * (w_old + s.angular_velocities[0]) * s.dt
    lost = E0 - energy()
    assert lost > 0.99 * 0.5 * (s.mass[0] + s.inertia[0] / a**2) * 0.02**2  # all but rest
    assert -work == pytest.approx(lost, rel=5e-3)  # measured 1.2e-4


def test_a_twelve_gon_comes_to_rest_only_with_rolling_resistance():
    free, _ = rolling_grain(ContactLaw(E=1e7, mu=0.8, gamma=0.3), sides=12, v0=0.05)
    held, _ = rolling_grain(ContactLaw(E=1e7, mu=0.8, gamma=0.3, mu_r=0.1), sides=12, v0=0.05)
    E0 = free.kinetic_energy()
    assert roll_to_rest(held, 0.3)
    free.advance(held.t)
    assert free.kinetic_energy() > 0.1 * E0


def test_two_grains_turning_together_feel_no_rolling_torque():
    law = ContactLaw(E=1e6, mu=0.5, gamma=0.3, mu_r=0.2)
    grains = [Particle(Polygon.regular(8, R, center=(x, 0.0)), 2650.0, angular_velocity=3.0)
              for x in (0.0, 2 * R * np.cos(np.pi / 8) - 2e-6)]
    s = DEMSystem(grains, law=law, gravity=(0.0, 0.0), overlap_tolerance=0.05)
    s.step()
    assert s.contacts.i.size == 1
    assert s.angular_velocities[0] == pytest.approx(s.angular_velocities[1], rel=1e-12)
    full = 0.2 * R * s.contacts.fn[0]  # mu_r R_r F_n with R_r ~ R / 2: twice it
    assert abs(s.contacts.mr[0]) < 1e-12 * full  # measured 4e-20 N m against 6e-8


@pytest.mark.skipif(not overlap_numba.AVAILABLE, reason="numba not installed")
def test_a_saved_state_continues_bit_for_bit():
    law = ContactLaw(E=1e7, mu=0.8, gamma=0.3, mu_r=0.1)
    A, _ = rolling_grain(law, sides=12)
    A.advance(5e-3)
    state = A.save_state()
    assert state["contact_mr"].shape == state["contact_keys"].shape
    assert np.abs(state["contact_mr"]).max() > 0
    B, _ = rolling_grain(law, sides=12)
    B.restore_state(state)
    A.advance(5e-3)
    B.advance(5e-3)
    assert np.array_equal(A.particles.q, B.particles.q)
    assert np.array_equal(A.contact_history.mr, B.contact_history.mr)


@pytest.mark.parametrize("field, value", [("mu_r", -0.1), ("eta_r", float("nan"))])
def test_bad_rolling_parameters_are_refused_by_name(field, value):
    with pytest.raises(ValueError, match=f"ContactLaw.{field} = "):
        ContactLaw(**{field: value})


def test_a_scene_sets_rolling_friction():
    sc = Scene.from_dict({"domain": {"box": [0, 0, 0.01, 0.01]},
                          "particles": [{"sides": 12, "radius": 1e-3,
                                         "center": [5e-3, 5e-3], "density": 2650.0}],
                          "contacts": {"mu_r": 0.15}, "effects": {"fluid": False},
                          "time": {"t_end": 1e-3, "dt": 1e-4}})
    assert sc.contact_law.mu_r == 0.15 and sc.contact_law.rolls
