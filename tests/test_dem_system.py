"""DEMSystem: input validation, coupling API, subcycling, checkpoints."""

import pickle

import numpy as np
import pytest

from skfem_granular.dem import (
    ContactLaw,
    DEMSystem,
    Particle,
    Polygon,
    box_walls,
)

R = 0.5e-3


def hexagon(x, y, **kw):
    return Particle(Polygon.regular(6, R, center=(x, y)), 2650.0, **kw)


def small_box_scene(**kw):
    parts = [hexagon(0.6e-3, 0.44e-3), hexagon(1.8e-3, 0.44e-3, velocity=(-0.05, 0.0)),
             hexagon(1.2e-3, 1.4e-3, angular_velocity=5.0)]
    return DEMSystem.in_box(parts, (0.0, 0.0, 3e-3, 11e-3), 0.5e-3,
                            law=ContactLaw(E=1e7, mu=0.4, gamma=0.2), **kw)


def test_paper_box_walls():
    # the paper's 3 x 11 mm fluid box with 0.5 mm DEM walls
    walls = box_walls(0.0, 0.0, 3e-3, 11e-3, 0.5e-3)
    assert len(walls) == 4
    inner = sum(w.area for w in walls)
    assert inner == pytest.approx((4e-3 * 12e-3) - 3e-3 * 11e-3, rel=1e-12)


def test_errors_name_particle_field_and_range():
    with pytest.raises(ValueError, match=r"particles\[1\]\.density = -1\.0: must be"):
        DEMSystem([hexagon(0, 0), Particle(Polygon.regular(6, R, center=(2e-3, 0)), -1.0)])
    with pytest.raises(ValueError, match=r"particles\[0\] and particles\[1\] overlap at start"):
        DEMSystem([hexagon(0, 0), hexagon(0.5 * R, 0)])
    with pytest.raises(ValueError, match=r"particles\[1\]\.shape spans .*must lie inside"):
        DEMSystem.in_box([hexagon(1e-3, 1e-3), hexagon(2.8e-3, 1e-3)],
                         (0.0, 0.0, 3e-3, 11e-3), 0.5e-3)
    with pytest.raises(ValueError, match=r"particles\[0\] and walls\[0\] overlap"):
        DEMSystem([hexagon(0.0, 0.2 * R)], [Polygon.rectangle(-1e-3, -1e-3, 1e-3, 0.0)])
    with pytest.raises(ValueError, match=r"signed area .*must be > 0"):
        DEMSystem([Particle(np.array([[0, 0, 1e-3], [0, 1e-3, 0]]), 1000.0)])
    with pytest.raises(ValueError, match=r"ContactLaw\.E = -5: must be finite and > 0"):
        ContactLaw(E=-5)
    s = DEMSystem([hexagon(0, 0)])
    with pytest.raises(ValueError, match=r"dt = .*: must be <= .* stable step .*particles\[0\]"):
        s.step(10 * s.dt_stable)
    with pytest.raises(ValueError, match=r"dt = .*: must be <="):
        DEMSystem([hexagon(0, 0)], dt=1.0)
    with pytest.raises(ValueError, match=r"dt_outer = -1: must be finite and > 0"):
        s.advance(-1)


def test_stable_step_estimate():
    s = DEMSystem([hexagon(0, 0), Particle(Polygon.regular(6, 0.5 * R, center=(3e-3, 0)),
                                           2650.0)], law=ContactLaw(E=2e7, gamma=0.3))
    m = 2650.0 * Polygon.regular(6, 0.5 * R).area
    assert s.dt_stable == pytest.approx(0.1 * np.pi * np.sqrt(m / 2e7), rel=1e-14)
    # strong damping is explicit in the predictor: the bound shrinks by 2 gamma
    s = DEMSystem([hexagon(0, 0)], law=ContactLaw(E=2e7, gamma=1.5))
    m = 2650.0 * Polygon.regular(6, R).area
    assert s.dt_stable == pytest.approx(0.1 * np.pi * np.sqrt(m / 2e7) / 3.0, rel=1e-14)


def test_free_fall_buoyancy_reduced_gravity():
    # a lone particle: g_eff = g (rho_p - rho_f A_core / A) / rho_p, exact for BDF2; the
    # default core is the shadow scaled by 0.8, so A_core / A = 0.64
    s = DEMSystem([hexagon(0.0, 0.0, velocity=(0.01, 0.0))], fluid_density=1000.0)
    n = s.advance(1e-3)
    assert n == int(np.ceil(1e-3 / s.dt_stable))
    assert s.particles.core_area[0] == pytest.approx(0.64 * s.particles.area[0], rel=1e-12)
    g = 9.81 * (2650.0 - 1000.0 * 0.64) / 2650.0
    assert s.velocities[1, 0] == pytest.approx(-g * 1e-3, rel=1e-12)
    assert s.positions[1, 0] == pytest.approx(-0.5 * g * 1e-6, rel=1e-10)
    assert s.positions[0, 0] == pytest.approx(1e-5, rel=1e-12)


def test_external_force_torque_and_callbacks():
    s = DEMSystem([hexagon(0.0, 0.0), hexagon(5e-3, 0.0)], gravity=(0.0, 0.0))
    s.external_force[:, 0] = (2.0, 0.0)
    s.external_torque[1] = 1e-6
    s.force_callbacks.append(lambda sys_, t: (np.array([[0.0, 0.0], [0.0, 3.0]]), np.zeros(2)))
    T = 1e-3
    s.advance(T)
    np.testing.assert_allclose(s.velocities[:, 0], [2.0 / s.mass[0] * T, 0.0], rtol=1e-12)
    np.testing.assert_allclose(s.velocities[:, 1], [0.0, 3.0 / s.mass[1] * T], rtol=1e-12)
    assert s.angular_velocities[1] == pytest.approx(1e-6 / s.inertia[1] * T, rel=1e-12)


def test_outlines_and_point_velocity():
    s = small_box_scene()
    s.advance(2e-4)
    sh, co = s.shadow_outlines(), s.core_outlines()
    assert len(sh) == len(co) == 3
    for k, (a, b) in enumerate(zip(sh, co, strict=True)):
        assert a.shape == b.shape == (2, 6)
        pa, pb = Polygon(a), Polygon(b)  # counter-clockwise and convex
        assert pb.area == pytest.approx(0.64 * pa.area, rel=1e-12)  # default core 0.8
        np.testing.assert_allclose(pa.centroid, s.positions[:, k], atol=1e-15)
    # rigid velocity V + omega x (x - X) at the vertices
    k = 2
    x = sh[k]
    u = s.point_velocity(k, x)
    d = x - s.positions[:, k : k + 1]
    w = s.angular_velocities[k]
    np.testing.assert_allclose(u, s.velocities[:, k : k + 1] + w * np.vstack([-d[1], d[0]]),
                               rtol=1e-14)
    body = s.bodies[k]
    np.testing.assert_allclose(body.point_velocity(x), u)
    assert body.mass == s.mass[k] and body.inertia == s.inertia[k]
    assert len(s.wall_outlines()) == 4


def test_advance_subcycles_equal_steps():
    s = small_box_scene()
    n = s.advance(10 * s.dt_stable + 1e-12)
    assert n == 11
    assert s.t == pytest.approx(10 * s.dt_stable + 1e-12, rel=1e-14)
    assert s.advance(1e-5, max_substep=1e-6) == 10


def test_save_restore_reproduces_trajectory_bitwise():
    s = small_box_scene()
    s.advance(3e-3)
    assert s.contacts.i.size > 0  # history in use
    state = s.save_state()
    s.advance(2e-3)
    ref = (s.positions.copy(), s.velocities.copy(), s.angles.copy())
    s.advance(1e-3)  # move on, then go back (through pickle, as a checkpoint file would)
    s.restore_state(pickle.loads(pickle.dumps(state)))
    s.advance(2e-3)
    np.testing.assert_array_equal(s.positions, ref[0])
    np.testing.assert_array_equal(s.velocities, ref[1])
    np.testing.assert_array_equal(s.angles, ref[2])


def test_body_views_write_through():
    s = small_box_scene()
    b = s.bodies[1]
    b.velocity = (0.1, 0.2)
    b.angular_velocity = 3.0
    assert s.velocities[:, 1].tolist() == [0.1, 0.2]
    assert s.angular_velocities[1] == 3.0


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_backends_agree(backend):
    from skfem_granular.dem import overlap_numba

    if backend == "numba" and not overlap_numba.AVAILABLE:
        pytest.skip("numba not installed")
    a = small_box_scene(backend="numpy")
    b = small_box_scene(backend=backend)
    for s in (a, b):
        s.advance(2e-3)
    np.testing.assert_allclose(b.positions, a.positions, rtol=0, atol=1e-12)


def test_contact_possible_within_a_step():
    """Bounding circles (radius R) grown by 3 (|v| dt + a dt^2) + R/10 each: two hexagons
    4 R apart at rest cannot touch within 1 ms; approaching at 0.5 m/s each (1.5 mm of
    reach each) they can; a circle 0.05 R above the floor is within reach, one 0.2 R above
    it at rest is not; an open contact always counts."""
    box = (0.0, 0.0, 10e-3, 10e-3)
    apart = DEMSystem.in_box([hexagon(3e-3, 5e-3), hexagon(5e-3, 5e-3)], box, 0.5e-3)
    assert not apart.contact_possible(1e-3, acceleration=9.81)
    moving = DEMSystem.in_box([hexagon(3e-3, 5e-3, velocity=(0.5, 0.0)),
                               hexagon(5e-3, 5e-3, velocity=(-0.5, 0.0))], box, 0.5e-3)
    assert moving.contact_possible(1e-3)
    assert not moving.contact_possible(1e-5)  # 15 um of reach each: still 1 mm apart
    assert DEMSystem.in_box([hexagon(5e-3, 1.05 * R)], box, 0.5e-3).contact_possible(1e-3)
    above = DEMSystem.in_box([hexagon(5e-3, 1.2 * R)], box, 0.5e-3)
    assert not above.contact_possible(1e-3, acceleration=9.81)  # reach 0.03 + 0.05 mm
    above.particles.v[1] = -0.02  # falling at 2 cm/s: 0.06 mm more
    assert above.contact_possible(1e-3, acceleration=9.81)
    landing = DEMSystem.in_box([hexagon(5e-3, R * np.sqrt(3) / 2 + 1e-6, velocity=(0, -0.05))],
                               box, 0.5e-3)
    while landing.contacts is None or not landing.contacts.i.size:  # down to the floor
        landing.advance(1e-6)
        assert landing.t < 1e-4
    assert landing.contact_possible(1e-12)
