"""A block on an inclined wall: sticks for tan(phi) < mu, slides for tan(phi) > mu."""

import numpy as np
import pytest

from skfem_granular.dem import ContactLaw, DEMSystem, Particle, Polygon, incline_wall

MU = 0.5
G = 9.81


def block_on_incline(phi, T=0.01, side=1e-3):
    """Square resting on a slab inclined at phi; returns times and down-slope velocity."""
    wall = incline_wall(phi, 20e-3, 2e-3)
    along = np.array([np.cos(phi), np.sin(phi)])
    normal = np.array([-np.sin(phi), np.cos(phi)])
    b = 5e-3 * along
    sq = np.column_stack([b, b + side * along, b + side * (along + normal), b + side * normal])
    s = DEMSystem([Particle(Polygon(sq), 2650.0)], [wall],
                  law=ContactLaw(E=1e7, mu=MU, gamma=0.5))
    t, v = [], []
    while s.t < T:
        s.step()
        t.append(s.t)
        v.append(-s.velocities[:, 0] @ along)  # positive down the slope
    return np.array(t), np.array(v), s


@pytest.mark.parametrize("tan_phi", [0.3, 0.45])
def test_block_sticks_below_friction_angle(tan_phi):
    phi = np.arctan(tan_phi)
    t, v, s = block_on_incline(phi)
    # after the initial normal transient the block is at rest: no mean acceleration
    # and its displacement stays below the elastic deflection of the tangential spring,
    # m g sin(phi) / k_t with k_t = (2/7) E l / L, l = side, L = 4 r0 = 2 side (wall)
    late = t > 0.004
    a = np.polyfit(t[late], v[late], 1)[0]
    assert abs(a) < 1e-4 * G * np.sin(phi)
    creep = np.trapezoid(v[late], t[late])
    kt = 2.0 / 7.0 * 1e7 / 2.0
    assert abs(creep) < s.mass[0] * G * np.sin(phi) / kt
    assert s.contacts.i.size == 1
    assert abs(s.contacts.ft[0]) < MU * s.contacts.fn[0]  # static friction, inside the cone


@pytest.mark.parametrize("tan_phi", [0.55, 0.7, 1.0])
def test_block_slides_with_coulomb_acceleration(tan_phi):
    phi = np.arctan(tan_phi)
    t, v, s = block_on_incline(phi)
    late = t > 0.004
    a = np.polyfit(t[late], v[late], 1)[0]
    ref = G * (np.sin(phi) - MU * np.cos(phi))
    assert a == pytest.approx(ref, rel=1e-4)
    assert abs(s.angular_velocities[0]) < 1e-3  # slides, does not tip
