"""Meshes graded by the flow as well as by the grains: an outside size in field meshes
(values at points or a callable, never below the outline edge, bounded in element
count, deterministic), the vorticity indicator, and the remesh that uses them."""

import numpy as np
import pytest

import meshing
from skfem_granular.coupled.flow_size import FlowSizing, vorticity
from skfem_granular.fluid import TaylorHood

BOX = (0.0, 0.0, 3e-3, 11e-3)


def disk(n=24, r=0.5e-3, c=(1.5e-3, 7.5e-3)):
    th = 2.0 * np.pi * np.arange(n) / n
    return np.vstack([c[0] + r * np.cos(th), c[1] + r * np.sin(th)])


DL = 2 * 0.5e-3 * np.sin(np.pi / 24)


def wake(x):
    """0.5 outline edges in a 1 x 3 mm strip below the disk, nothing asked elsewhere."""
    inside = (np.abs(x[0] - 1.5e-3) < 0.5e-3) & (x[1] > 3.5e-3) & (x[1] < 6.5e-3)
    return np.where(inside, 0.5 * DL, 1.0)


def in_strip(p):
    return (np.abs(p[0] - 1.5e-3) < 0.5e-3) & (p[1] > 3.5e-3) & (p[1] < 6.5e-3)


def test_outside_size_refines_where_asked_and_never_below_the_outline_edge():
    plain = meshing.build("field", BOX, [disk()]).mesh
    fine = meshing.build("field", BOX, [disk()], size=wake).mesh
    e = np.unique(np.sort(np.hstack([fine.t[[0, 1]], fine.t[[1, 2]], fine.t[[2, 0]]]),
                          axis=0), axis=1)
    mid = 0.5 * (fine.p[:, e[0]] + fine.p[:, e[1]])
    L = np.hypot(*(fine.p[:, e[0]] - fine.p[:, e[1]]))
    strip = in_strip(mid)
    # the floor: the outline edge, not the half asked for (measured: mean 1.09 DL; 182
    # vertices in the strip against 18, 482 in all against 263; 28.6 deg)
    assert 0.9 * DL < np.mean(L[strip]) < 1.3 * DL
    assert np.sum(in_strip(fine.p)) > 3 * np.sum(in_strip(plain.p))
    s = meshing.mesh_stats(fine)
    assert s.min_angle >= 20.0 and s.max_aspect <= 3.0
    # far from the strip and the disk the rule is unchanged: the same vertices up there
    top = lambda p: p[:, p[1] > 10e-3]  # noqa: E731
    assert abs(top(fine.p).shape[1] - top(plain.p).shape[1]) <= 2


def test_sizes_at_points_and_determinism():
    """(points, values) interpolated linearly: the same mesh every time, and about the
    mesh of the same function as a callable (the interpolant differs by rounding)."""
    X, Y = np.meshgrid(np.linspace(0.0, 3e-3, 31), np.linspace(0.0, 11e-3, 111))
    pts = np.vstack([X.ravel(), Y.ravel()])
    vals = 0.2e-3 + 0.1 * np.abs(pts[1] - 5e-3)
    a = meshing.build("field", BOX, [disk()], size=(pts, vals)).mesh
    b = meshing.build("field", BOX, [disk()], size=(pts, vals)).mesh
    c = meshing.build("field", BOX, [disk()],
                      size=lambda x: 0.2e-3 + 0.1 * np.abs(x[1] - 5e-3)).mesh
    np.testing.assert_array_equal(a.p, b.p)
    np.testing.assert_array_equal(a.t, b.t)
    assert a.p.shape[1] == pytest.approx(c.p.shape[1], rel=0.03)


@pytest.mark.parametrize("size, message", [
    (lambda x: np.ones(3), "the callable must return shape"),
    (lambda x: -np.ones(x.shape[1]), "the callable must return finite sizes > 0"),
    ((np.zeros((3, 4)), np.ones(4)), "points must be \\(2, N\\)"),
    ("fine", "expected a callable"),
])
def test_bad_size_names_the_field(size, message):
    with pytest.raises(ValueError, match="size: " + message):
        meshing.build("field", BOX, [disk()], size=size)


def test_outside_size_is_bounded_by_max_elements():
    with pytest.raises(ValueError, match="max_elements = 2000"):
        meshing.build("field", BOX, [disk()], size=lambda x: np.full(x.shape[1], 1e-9),
                      max_elements=2000)


@pytest.fixture(scope="module")
def space():
    return TaylorHood(meshing.build("field", BOX, [disk()]).mesh)


def test_vorticity_of_linear_flows_is_exact(space):
    X = space.sb.doflocs
    u = np.empty(space.nu)
    u[0::2], u[1::2] = -3.0 * X[1], 3.0 * X[0]            # rigid rotation: omega = 6
    np.testing.assert_allclose(vorticity(space, u), 6.0, rtol=1e-12)
    u[0::2], u[1::2] = 2.0 * X[1] + 1.0, 0.0 * X[0]       # shear: omega = -2
    np.testing.assert_allclose(vorticity(space, u), -2.0, rtol=1e-12)


def test_flow_sizing_follows_the_vortex_within_the_budget(space):
    """A Lamb-Oseen-like vortex below the disk: fine there, the budget's floor kept.
    Measured (sizes graded at sigma - 1 before use): 460 triangles without; budget 400:
    509 (floor 0.43 mm), budget 4000: 778 (floor 0.14 mm), 39 vertices within 0.5 mm of
    the vortex against 4."""
    X = space.sb.doflocs
    r2 = (X[0] - 1.5e-3) ** 2 + (X[1] - 5e-3) ** 2
    g = np.exp(-r2 / (0.4e-3) ** 2)
    u = np.empty(space.nu)
    u[0::2], u[1::2] = -(X[1] - 5e-3) * g * 100.0, (X[0] - 1.5e-3) * g * 100.0
    for budget in (400, 4000):
        sizing = FlowSizing(eps=0.1, budget=budget)
        pts, h = sizing(space, u)
        assert h.min() == pytest.approx(sizing.floor(space), rel=1e-12)
        mesh = meshing.build("field", BOX, [disk()], size=(pts, h)).mesh
        again = meshing.build("field", BOX, [disk()], size=sizing(space, u)).mesh
        np.testing.assert_array_equal(mesh.p, again.p)      # deterministic
        near = np.hypot(mesh.p[0] - 1.5e-3, mesh.p[1] - 5e-3) < 0.5e-3
        plain = meshing.build("field", BOX, [disk()]).mesh
        base = meshing.mesh_stats(plain).n_triangles
        assert mesh.t.shape[1] <= base + budget     # the flow's share within the budget
        if budget == 4000:
            near_plain = np.hypot(plain.p[0] - 1.5e-3, plain.p[1] - 5e-3) < 0.5e-3
            assert near.sum() > 2 * near_plain.sum()
    with pytest.raises(ValueError, match="FlowSizing.eps"):
        FlowSizing(eps=0.0)


def test_point_sizes_are_graded_before_interpolation():
    """h_i = min_j (h_j + slope |x_i - x_j|): a size of 0.1 next to 10 at distance 1
    becomes 0.1 + slope; the field mesh grades outside sizes at its own sigma - 1."""
    from meshing.size_input import graded_values

    P = np.array([[0.0, 1.0, 3.0], [0.0, 0.0, 0.0]])
    np.testing.assert_allclose(graded_values(P, np.array([0.1, 10.0, 0.2]), 0.2),
                               [0.1, 0.3, 0.2], rtol=1e-15)
    # a single small size at one point spreads over the distance the slope allows
    X, Y = np.meshgrid(np.linspace(0.0, 3e-3, 13), np.linspace(0.0, 11e-3, 45))
    pts = np.vstack([X.ravel(), Y.ravel()])
    vals = np.full(pts.shape[1], 3e-3)
    k = int(np.argmin(np.hypot(pts[0] - 1.5e-3, pts[1] - 3e-3)))
    vals[k] = DL
    mesh = meshing.build("field", BOX, [disk()], size=(pts, vals)).mesh
    plain = meshing.build("field", BOX, [disk()]).mesh
    near = lambda m: int(np.sum(np.hypot(m.p[0] - 1.5e-3, m.p[1] - 3e-3) < 1e-3))  # noqa: E731
    assert near(mesh) > 3 * near(plain)
    assert meshing.mesh_stats(mesh).min_angle >= 20.0
