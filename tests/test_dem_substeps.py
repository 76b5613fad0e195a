"""The compiled substep loop against the numpy pipeline, step by step.

:meth:`DEMSystem.advance` runs its substeps in one compiled call
(:mod:`skfem_granular.dem.substeps_numba`) where it can; :meth:`DEMSystem.step` is
the numpy pipeline, one substep per call. Both do the same arithmetic in the same
order, so a dense pile (about one contact per grain, walls, Verlet rebuilds inside
the window, a friction-limited tangential history) must come out of both the same
up to the last bits of ``cos``/``sin`` (on the development machine: bit for bit);
chaos amplifies such bits, so the window is short (200 substeps) and the bounds
(positions to 1e-12 of a grain radius, velocities and forces to 1e-9 of their
largest) leave room for that amplification and none for a wrong term.
"""

import numpy as np
import pytest

from skfem_granular.dem import ContactLaw, DEMSystem, Particle, Polygon, overlap_numba

pytestmark = pytest.mark.skipif(not overlap_numba.AVAILABLE, reason="numba not installed")

R = 0.5e-3


def pile(n=40, seed=3, law=None, **kwargs):
    """``n`` 6-10-gons dropped on a grid in a closed box, then settled for 3000 steps."""
    rng = np.random.default_rng(seed)
    cols = 8
    parts = [Particle(Polygon.regular(int(rng.integers(6, 11)), R * rng.uniform(0.8, 1.0),
                                      center=((k % cols + 0.5) * 2 * R,
                                              (k // cols + 0.5) * 2.04 * R),
                                      angle=rng.uniform(0, 2 * np.pi)),
                      2650.0, velocity=rng.normal(0.0, 0.02, 2))
             for k in range(n)]
    rows = -(-n // cols)
    s = DEMSystem.in_box(parts, (0.0, 0.0, cols * 2 * R, rows * 2.04 * R + 2 * R), 0.5e-3,
                         law=law or ContactLaw(E=1e6, mu=0.3, gamma=0.3), **kwargs)
    for _ in range(3000):
        s.step()
    return s


def twins(law=None):
    A = pile(law=law)
    B = pile(law=law)
    assert np.array_equal(A.particles.q, B.particles.q)
    return A, B


def assert_same(A, B):
    vmax = np.abs(B.particles.v[:2]).max()
    assert A.steps == B.steps and A.t == pytest.approx(B.t, rel=1e-15)
    assert np.abs(A.particles.q[:2] - B.particles.q[:2]).max() < 1e-12 * R
    assert np.abs(A.particles.v[:2] - B.particles.v[:2]).max() < 1e-9 * vmax
    assert np.array_equal(A.contact_history.keys, B.contact_history.keys)
    fmax = np.abs(B.contacts.fn).max()
    assert np.abs(A.contact_history.ft - B.contact_history.ft).max() < 1e-9 * fmax
    assert np.array_equal(A.contacts.i, B.contacts.i)
    assert np.abs(A.contacts.fn - B.contacts.fn).max() < 1e-9 * fmax
    assert np.abs(A.force - B.force).max() < 1e-9 * np.abs(B.force).max()


def test_advance_matches_the_numpy_pipeline_through_contacts_and_rebuilds():
    A, B = twins()
    dt = A.dt
    builds = A.neighbours.builds
    for _ in range(8):
        assert A.advance(25 * dt) == 25
    for _ in range(200):
        B.step(dt)
    assert A.neighbours.builds == B.neighbours.builds
    assert A.neighbours.builds > builds  # a rebuild fell inside the window
    assert A.contacts.i.size >= 0.9 * A.n  # a pile: about one contact per grain
    slipping = np.abs(np.abs(B.contacts.ft) - B.law.mu * B.contacts.fn) < 1e-12 * B.contacts.fn
    assert slipping.any() and not slipping.all()  # both branches of the Coulomb limit
    assert_same(A, B)


def test_a_step_larger_than_twice_the_last_restarts_as_in_the_numpy_pipeline():
    A, B = twins()
    dt = A.dt
    A.step(0.25 * dt)
    B.step(0.25 * dt)
    A.advance(30 * dt)  # first substep: ratio 4 > MAX_STEP_RATIO, a BDF2 restart
    for _ in range(30):
        B.step(dt)
    assert_same(A, B)


def test_force_callbacks_are_evaluated_at_every_substep():
    A, B = twins()
    calls = []

    def lift(system, t):  # half the weight, upwards
        calls.append(t)
        return np.outer((0.0, 4.905), system.mass), np.zeros(system.n)

    for s in (A, B):
        s.force_callbacks.append(lift)
    A.advance(50 * A.dt)
    assert len(calls) == 50
    for _ in range(50):
        B.step(B.dt)
    assert_same(A, B)


def test_rolling_resistance_matches_the_numpy_pipeline():
    """With rolling resistance (both branches of its limit in the window) the compiled
    loop and the numpy pipeline give the same torques, springs and motion."""
    A, B = twins(ContactLaw(E=1e6, mu=0.3, gamma=0.3, mu_r=0.1))
    dt = A.dt
    for _ in range(8):
        A.advance(25 * dt)
    for _ in range(200):
        B.step(dt)
    assert_same(A, B)
    mmax = np.abs(B.contacts.mr).max()
    assert mmax > 0
    assert np.abs(A.contacts.mr - B.contacts.mr).max() < 1e-9 * mmax
    assert np.abs(A.contact_history.mr - B.contact_history.mr).max() < 1e-9 * mmax
    assert np.abs(A.torque - B.torque).max() < 1e-9 * np.abs(B.torque).max()
    held = B.contacts.mr == B.contacts.mr_spring  # at the limit the dashpot is off
    assert held.any() and not held.all()  # both branches of the rolling limit
