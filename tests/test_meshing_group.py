"""Particle groups: fine region inside a circle or sector, graded outside, conforming."""

import numpy as np
import pytest

import meshing
from meshing import graded

BOX = (0.0, 0.0, 10e-3, 30e-3)


def regular(n, r, c, rot=0.0):
    th = rot + 2.0 * np.pi * np.arange(n) / n
    return np.vstack([c[0] + r * np.cos(th), c[1] + r * np.sin(th)])


def lattice(nx, ny, c, pitch=0.5e-3, r=0.2e-3, n=12, seed=0):
    rng = np.random.default_rng(seed)
    return [regular(n, r, (c[0] + (i - (nx - 1) / 2) * pitch, c[1] + j * pitch), rng.uniform(0, 1))
            for i in range(nx) for j in range(ny)]


@pytest.fixture(scope="module")
def hundred():
    parts = lattice(10, 10, (5e-3, 7.75e-3))
    return parts, meshing.build("group", BOX, parts)


def check_conforming(mesh, center, radius):
    fine = np.zeros(mesh.t.shape[1], dtype=bool)
    fine[mesh.subdomains["fine"]] = True
    assert np.all(fine | np.isin(np.arange(fine.size), mesh.subdomains["graded"]))
    assert not np.any(np.isin(mesh.subdomains["fine"], mesh.subdomains["graded"]))
    f2t = mesh.f2t
    interior = f2t[1] >= 0
    a, b = fine[f2t[0]], np.where(interior, fine[np.maximum(f2t[1], 0)], False)
    trans = np.flatnonzero(interior & (a != b))
    # every fine-region edge is a named boundary or shared with exactly one graded triangle
    n_fine_sides = np.where(interior, a.astype(int) + b.astype(int), a.astype(int))
    one_fine = np.flatnonzero(n_fine_sides == 1)
    named = np.concatenate([v for k, v in mesh.boundaries.items() if k != "wall"] +
                           [mesh.boundaries["wall"]])
    assert set(one_fine) == set(trans) | (set(one_fine) & set(named))
    # transition nodes on the circle, each used by fine and graded triangles
    nodes = np.unique(mesh.facets[:, trans])
    r = np.hypot(*(mesh.p[:, nodes] - np.asarray(center)[:, None]))
    on_wall = np.zeros(nodes.size, dtype=bool)
    x0, y0, x1, y1 = BOX
    px, py = mesh.p[:, nodes]
    on_wall |= (px == x0) | (px == x1) | (py == y0) | (py == y1)
    np.testing.assert_allclose(r[~on_wall], radius, rtol=1e-12)
    for v in nodes:
        tris = np.flatnonzero(np.any(mesh.t == v, axis=0))
        assert fine[tris].any() and (~fine[tris]).any()
    # no hanging node: no vertex lies inside a transition edge
    A, B = mesh.p[:, mesh.facets[0, trans]], mesh.p[:, mesh.facets[1, trans]]
    near = np.flatnonzero(np.abs(np.hypot(*(mesh.p - np.asarray(center)[:, None])) - radius)
                          < 0.05 * radius)
    for k in range(trans.size):
        e = B[:, k] - A[:, k]
        w = mesh.p[:, near] - A[:, k:k + 1]
        t = (e @ w) / (e @ e)
        dist = np.abs(e[0] * w[1] - e[1] * w[0]) / np.hypot(*e)
        inner = (t > 1e-9) & (t < 1 - 1e-9) & (dist < 1e-9 * radius)
        assert not inner.any()
    # no facet is a boundary facet unless it is named
    np.testing.assert_array_equal(np.sort(mesh.boundary_facets()), np.unique(named))
    return trans


def test_hundred_particles_conforming_and_quality(hundred):
    parts, value = hundred
    mesh = value.mesh
    c = np.mean([p.mean(axis=1) for p in parts], axis=0)
    radius = max(np.max(np.hypot(*(p - c[:, None]))) for p in parts) + 2 * 2 * 0.2e-3 * np.sin(
        np.pi / 12)
    trans = check_conforming(mesh, c, radius)
    n_circle = max(16, int(np.ceil(2 * np.pi * radius / (2 * 0.2e-3 * np.sin(np.pi / 12)))))
    assert trans.size == n_circle
    s = meshing.mesh_stats(mesh)
    assert s.min_angle >= 20.0 and s.max_aspect <= 3.0 and s.n_inverted == 0
    assert {f"particle{k}" for k in range(100)} <= set(mesh.boundaries)
    for k, P in enumerate(parts):
        np.testing.assert_array_equal(mesh.p[:, value.particle_nodes[k]], P)
        assert mesh.boundaries[f"particle{k}"].size == 12


def test_graded_outside_grows_by_sigma_per_circle(hundred):
    """Outside the circle the graded nodes (before relaxation) sit on circles whose
    spacing starts at the transition edge and grows by sigma = 1.2 per circle."""
    parts, _ = hundred
    mesh = meshing.group_mesh(BOX, parts, relax_rounds=0)
    c = np.mean([p.mean(axis=1) for p in parts], axis=0)
    h = 2 * 0.2e-3 * np.sin(np.pi / 12)
    radius = max(np.max(np.hypot(*(p - c[:, None]))) for p in parts) + 2 * h
    n = max(16, int(np.ceil(2 * np.pi * radius / h)))
    dl = 2 * radius * np.sin(np.pi / n)
    radii = radius + dl * (1.2 ** np.arange(60) - 1.0) / 0.2
    np.testing.assert_allclose(graded.ring_radii(radius, 1.2, 40e-3, dl),
                               radii[:graded.ring_radii(radius, 1.2, 40e-3, dl).size], rtol=1e-12)
    g = np.unique(mesh.t[:, mesh.subdomains["graded"]])
    r = np.hypot(*(mesh.p[:, g] - c[:, None]))
    x0, y0, x1, y1 = BOX
    px, py = mesh.p[:, g]
    interior = (px > x0) & (px < x1) & (py > y0) & (py < y1)
    d = np.min(np.abs(r[interior, None] - radii[None, :]), axis=1) / r[interior]
    assert np.mean(d < 1e-9) > 0.9


def test_sector_on_the_bottom_wall():
    parts = lattice(5, 3, (5e-3, 0.3e-3))
    mesh = meshing.group_mesh((0.0, 0.0, 10e-3, 10e-3), parts, center=(5e-3, 0.0))
    s = meshing.mesh_stats(mesh)
    assert s.min_angle >= 20.0 and s.max_aspect <= 3.0 and s.n_inverted == 0
    fine = mesh.subdomains["fine"]
    bottom = mesh.boundaries["bottom"]
    f2t = mesh.f2t[0, bottom]
    assert np.isin(f2t, fine).sum() >= 10          # the sector sits on the wall
    np.testing.assert_array_equal(mesh.p[1, mesh.facets[:, bottom]], 0.0)


@pytest.mark.parametrize("sigma", [None, 1.05, 1.5])
def test_single_particle_group_and_sigma(sigma):
    P = regular(24, 0.5e-3, (1.5e-3, 5.5e-3))
    mesh = meshing.group_mesh((0.0, 0.0, 3e-3, 11e-3), [P], radius=0.9e-3, sigma=sigma)
    s = meshing.mesh_stats(mesh)
    assert s.min_angle >= 20.0 and s.max_aspect <= 3.0


def test_faster_growth_means_fewer_graded_nodes(hundred):
    parts, value = hundred
    mesh = value.mesh
    slow = meshing.group_mesh(BOX, parts, sigma=1.05)
    n_slow = np.unique(slow.t[:, slow.subdomains["graded"]]).size
    n_fast = np.unique(mesh.t[:, mesh.subdomains["graded"]]).size
    # node count per unit area ~ 1 / spacing^2 with spacing growing (sigma - 1) per
    # unit radius: four times faster growth must save well over half the nodes
    assert n_fast < 0.5 * n_slow


def crossing_angles(mesh, center, radius, box):
    """Angles (deg) at which the transition circle meets the walls it crosses."""
    x0, y0, x1, y1 = box
    c = np.asarray(center)
    d = np.array([c[1] - y0, x1 - c[0], y1 - c[1], c[0] - x0])
    return np.degrees(np.arccos(d[d < radius] / radius))


@pytest.mark.parametrize("shift", [0.0, 0.3e-3, 0.55e-3])
def test_default_circle_never_grazes_a_wall(shift):
    """A group near the right wall: the default circle shrinks, moves onto the
    wall or grows, so that it crosses walls at >= 60 degrees; quality holds."""
    box = (0.0, 0.0, 4e-3, 8e-3)
    parts = lattice(2, 2, (2.6e-3 + shift, 3.5e-3), pitch=0.7e-3, r=0.25e-3)
    from meshing.group import fit_circle
    allv = np.hstack(parts)
    c0 = np.mean([p.mean(axis=1) for p in parts], axis=0)
    D = np.array([[0, 4e-3, 4e-3, 0], [0, 0, 8e-3, 8e-3]])
    h = 2 * 0.25e-3 * np.sin(np.pi / 12)
    c, R = fit_circle(D, allv, c0, None, h, free_center=True)
    ang = crossing_angles(None, c, R, box)
    assert np.all(ang >= 60.0 - 1e-6)
    gaps = np.array([c[1], 4e-3 - c[0], 8e-3 - c[1], c[0]]) - R
    assert np.all((gaps >= h - 1e-12) | (gaps <= -R * 0.5 + 1e-12))
    mesh = meshing.group_mesh(box, parts)
    s = meshing.mesh_stats(mesh)
    assert s.min_angle >= 20.0 and s.max_aspect <= 3.0


def test_given_radius_grazing_a_wall_is_rejected():
    parts = lattice(1, 1, (2e-3, 4e-3), r=0.25e-3)
    with pytest.raises(ValueError, match=r"radius: the circle meets domain edge 1 at \d+ "
                                         r"degrees or passes within h of it; use radius <="):
        meshing.group_mesh((0.0, 0.0, 3e-3, 8e-3), parts, radius=0.95e-3)
