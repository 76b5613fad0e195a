"""Binary collisions: conservation laws and restitution (DEMSystem)."""

import numpy as np
import pytest

from skfem_granular.dem import ContactLaw, DEMSystem, Particle, Polygon

R = 0.5e-3
RHO = 2650.0


def collide(p0, p1, law, dt_factor=0.1, t_max=5e-3):
    """Run until the pair has touched and separated again; return the system."""
    s = DEMSystem([p0, p1], law=law, gravity=(0.0, 0.0))
    dt = dt_factor * s.dt_stable
    touched = False
    while s.t < t_max:
        s.step(dt)
        n = s.contacts.i.size
        touched |= n > 0
        if touched and n == 0:
            return s
    raise AssertionError("collision did not finish")


def angular_momentum(s, p):
    """L about the fixed point p: sum m (x - p) x v + I omega."""
    x, v = s.positions - np.asarray(p)[:, None], s.velocities
    return float((s.mass * (x[0] * v[1] - x[1] * v[0]) + s.inertia * s.angular_velocities).sum())


def oblique_pair():
    A = Particle(Polygon.regular(6, R, center=(0.0, 0.0), angle=0.2), RHO,
                 velocity=(0.2, 0.05), angular_velocity=30.0)
    B = Particle(Polygon.regular(4, 0.8 * R, center=(1.9 * R, 0.6 * R), angle=0.5), 1.5 * RHO,
                 velocity=(-0.1, 0.0), angular_velocity=-10.0)
    return A, B


@pytest.mark.parametrize("mu", [0.0, 0.5])
def test_contact_forces_balance_to_roundoff(mu):
    # every evaluation: sum of forces = 0 and sum of torques about any fixed point = 0
    A, B = oblique_pair()
    s = DEMSystem([A, B], law=ContactLaw(E=1e7, mu=mu, gamma=0.3), gravity=(0.0, 0.0))
    dt = 0.1 * s.dt_stable
    checked = 0
    while s.t < 2e-3:
        s.step(dt)
        s.evaluate(s.particles.q, s.particles.v, s.t, 0.0)  # forces at the current state
        if s.contacts.i.size:
            F, T, X = s.force, s.torque, s.positions
            fscale = np.abs(F).max()
            assert np.abs(F.sum(axis=1)).max() <= 1e-14 * fscale
            for p in [(0.0, 0.0), (3e-3, -2e-3)]:
                d = X - np.asarray(p)[:, None]
                Lrate = (d[0] * F[1] - d[1] * F[0] + T).sum()
                assert abs(Lrate) <= 1e-14 * fscale * (np.abs(d).max() + R)
            checked += 1
    assert checked > 20


@pytest.mark.parametrize("mu", [0.0, 0.5])
def test_momentum_conserved_in_oblique_collision(mu):
    # hexagon hitting a rotated square off-centre, with friction and damping.
    # Linear momentum: BDF2 is linear, so P is conserved to round-off.
    # Angular momentum is quadratic (x cross v): BDF2 conserves it only up to its
    # truncation error, which must shrink as dt^2 (the torque balance itself is
    # exact, test above).
    A, B = oblique_pair()
    s0 = DEMSystem([A, B], gravity=(0.0, 0.0))
    P0 = (s0.mass * s0.velocities).sum(axis=1)
    pts = [(0.0, 0.0), (3e-3, -2e-3)]
    L0 = [angular_momentum(s0, p) for p in pts]
    errors = []
    for dt_factor in (0.1, 0.05):
        s = collide(A, B, ContactLaw(E=1e7, mu=mu, gamma=0.3), dt_factor=dt_factor)
        assert s.steps > 50
        assert np.abs(s.angular_velocities).max() > 1.0  # rotation was exchanged
        P = (s.mass * s.velocities).sum(axis=1)
        scale = float(np.abs(s.mass * s.velocities).sum())
        np.testing.assert_allclose(P, P0, rtol=0, atol=1e-14 * scale)
        Lscale = float((s.mass * R * np.abs(s.velocities).sum(axis=0)).sum())
        errors.append(max(abs(angular_momentum(s, p) - L) for p, L in zip(pts, L0, strict=True))
                      / Lscale)
    assert errors[0] < 1e-6
    assert errors[1] < errors[0] / 3.0  # second order: ratio ~4 for halved dt


def test_energy_conserved_without_damping_within_one_percent():
    # frictionless, undamped, oblique hexagon-hexagon collision with rotation
    A = Particle(Polygon.regular(6, R, center=(0.0, 0.0)), RHO, velocity=(0.3, 0.0))
    B = Particle(Polygon.regular(6, R, center=(2.2 * R, 0.4 * R), angle=0.3), RHO,
                 velocity=(-0.3, 0.0))
    s0 = DEMSystem([A, B], gravity=(0.0, 0.0))
    E0 = s0.kinetic_energy()
    s = collide(A, B, ContactLaw(E=1e7, mu=0.0, gamma=0.0), dt_factor=0.1)
    assert abs(s.kinetic_energy() / E0 - 1.0) < 0.01
    assert np.abs(s.angular_velocities).max() > 1.0


def restitution(gamma, dt_factor=0.1):
    v = 0.2
    A = Particle(Polygon.rectangle(0, 0, 2 * R, 2 * R), RHO, velocity=(v, 0.0))
    # head-on, flat faces (collinear top/bottom edges): no rotation is excited
    B = Particle(Polygon.rectangle(2.02 * R, 0.0, 4.02 * R, 2 * R), RHO, velocity=(-v, 0.0))
    s = collide(A, B, ContactLaw(E=1e7, mu=0.0, gamma=gamma), dt_factor=dt_factor)
    assert np.abs(s.angular_velocities).max() < 1e-9 and np.abs(s.velocities[1]).max() < 1e-12
    return (s.velocities[0, 1] - s.velocities[0, 0]) / (2 * v)


def test_restitution_decreases_monotonically_with_damping():
    gammas = [0.0, 0.05, 0.1, 0.2, 0.4, 0.8]
    e = np.array([restitution(g) for g in gammas])
    assert abs(e[0] - 1.0) < 0.01  # elastic within the BDF2 dissipation
    assert np.all(np.diff(e) < 0)
    assert 0.0 <= e[-1] < 0.5


def test_damping_never_attracts():
    # with strong damping the normal force is limited to >= 0: the pair separates
    # with non-negative relative velocity, never sticks together
    e = restitution(5.0)
    assert e >= 0.0
