"""Contact law, contact history and broad phase as separate stages."""

import numpy as np
import pytest

from skfem_granular.dem import ContactHistory, ContactLaw
from skfem_granular.dem.broadphase import NeighbourList, circle_pairs, wall_pairs
from skfem_granular.dem.contact_law import contact_forces


def one_contact(law, vn=0.0, vt=0.0, ft_old=0.0, wall=False, dt=1e-6):
    """Contact at point (1, 0) between centroids (0, 0) and (3, 0), normal +x.

    r0 = 1, r1 = 2: L = 4 * 1 * 2 / 3 = 8/3 (walls: L = 4 r0 = 4); A = 0.01, l = 0.2.
    Body i moves with (vn, vt), body j rests.
    """
    col = lambda *x: np.array(x, dtype=float).reshape(-1, 1)  # noqa: E731
    return contact_forces(law, np.array([0.01]), col(1.0, 0.0), col(1.0, 0.0), np.array([0.2]),
                          col(0.0, 0.0), col(3.0, 0.0), col(vn, vt), col(0.0, 0.0),
                          np.array([0.0]), np.array([0.0]), np.array([2.0]), np.array([wall]),
                          np.array([ft_old]), dt)


def test_elastic_normal_force_and_characteristic_length():
    law = ContactLaw(E=3.0, mu=0.5, gamma=0.0)
    fn, ft, spring, energy = one_contact(law)
    assert fn[0] == pytest.approx(3.0 * 0.01 / (8.0 / 3.0), rel=1e-14)
    assert ft[0] == 0.0
    # energy estimate E A^2 / (2 L l)
    assert energy[0] == pytest.approx(3.0 * 1e-4 / (2 * 8.0 / 3.0 * 0.2), rel=1e-14)
    fn_wall = one_contact(law, wall=True)[0]
    assert fn_wall[0] == pytest.approx(3.0 * 0.01 / 4.0, rel=1e-14)


def test_damping_value_and_limits():
    law = ContactLaw(E=3.0, mu=0.5, gamma=0.1, damping_cap=2.0)
    fel = 3.0 * 0.01 / (8.0 / 3.0)
    vn = 1e-3
    fn = one_contact(law, vn=vn)[0][0]
    # gamma sqrt(m_eff E) (dA/dt) / L with dA/dt = l vn
    assert fn - fel == pytest.approx(0.1 * np.sqrt(2.0 * 3.0) * 0.2 * vn / (8.0 / 3.0), rel=1e-12)
    assert one_contact(law, vn=1e6)[0][0] == pytest.approx(3.0 * fel, rel=1e-14)  # capped
    assert one_contact(law, vn=-1e6)[0][0] == 0.0  # never attracts


def test_tangential_spring_and_coulomb_limit():
    law = ContactLaw(E=3.0, mu=0.5, gamma=0.0)
    fel = 3.0 * 0.01 / (8.0 / 3.0)
    kt = 2.0 / 7.0 * 3.0 * 0.2 / (8.0 / 3.0)
    dt = 1e-3
    fn, ft, spring, _ = one_contact(law, vt=1e-3, ft_old=1e-4, dt=dt)
    assert spring[0] == pytest.approx(1e-4 - kt * 1e-3 * dt, rel=1e-14)  # stick: spring grows
    assert ft[0] == spring[0]
    fn, ft, spring, _ = one_contact(law, vt=1e3, dt=dt)
    assert ft[0] == pytest.approx(-0.5 * fel, rel=1e-14)  # slip: Coulomb limit, opposes motion
    assert spring[0] == ft[0]


def test_contact_history_persists_and_drops():
    h = ContactHistory()
    h.replace(np.array([7, 3, 11]), np.array([0.7, 0.3, 1.1]))
    np.testing.assert_array_equal(h.lookup(np.array([3, 5, 11])), [0.3, 0.0, 1.1])
    h.replace(np.array([11]), np.array([2.0]))  # pairs 3 and 7 separated: dropped
    np.testing.assert_array_equal(h.lookup(np.array([3, 7, 11])), [0.0, 0.0, 2.0])


def test_circle_pairs_against_brute_force():
    rng = np.random.default_rng(3)
    X = rng.uniform(0, 1, (2, 300))
    r = rng.uniform(0.005, 0.03, 300)
    i, j = circle_pairs(X, r, margin=0.01)
    d = np.hypot(*(X[:, :, None] - X[:, None, :]))
    bi, bj = np.nonzero(np.triu(d < r[:, None] + r[None, :] + 0.01, k=1))
    assert set(zip(i.tolist(), j.tolist(), strict=True)) == set(
        zip(bi.tolist(), bj.tolist(), strict=True))


def test_wall_pairs_distance_to_polygon():
    wall = np.array([[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]])  # unit square
    X = np.array([[0.5, 1.05, 1.2, 0.5, 1.07], [0.5, 0.5, 0.5, -0.04, 1.07]])
    i, w = wall_pairs(X, np.full(5, 0.06), wall)
    # inside, 0.05 right, 0.2 right, 0.04 below, corner distance 0.099
    assert i.tolist() == [0, 1, 3]


def test_neighbour_list_rebuilds_after_half_margin():
    X = np.array([[0.0, 1.0], [0.0, 0.0]])
    r = np.array([0.4, 0.4])
    nl = NeighbourList(margin=0.4)
    nl.update(X, r, np.zeros((0, 3, 2)))
    assert nl.builds == 1 and nl.pairs[0].tolist() == [0]
    nl.update(X + 0.1, r, np.zeros((0, 3, 2)))
    assert nl.builds == 1  # moved less than margin / 2
    Y = X.copy()
    Y[0, 1] = 2.0
    nl.update(Y, r, np.zeros((0, 3, 2)))
    assert nl.builds == 2 and nl.pairs[0].size == 0
