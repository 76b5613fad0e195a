"""Equidistant (fine) meshes: counts against the paper, size, quality, boundaries."""

import numpy as np
import pytest

import meshing
from meshing import geometry

BOX = (0.0, 0.0, 3e-3, 11e-3)
PAPER_FINE_NODES = 8914


def regular(n, r=0.5e-3, c=(1.5e-3, 5.5e-3), rot=0.0):
    th = rot + 2.0 * np.pi * np.arange(n) / n
    return np.vstack([c[0] + r * np.cos(th), c[1] + r * np.sin(th)])


def edge_lengths(mesh):
    return np.hypot(*(mesh.p[:, mesh.facets[0]] - mesh.p[:, mesh.facets[1]]))


@pytest.fixture(scope="module")
def fine24_value():
    return meshing.build("uniform", BOX, [regular(24)])


@pytest.fixture(scope="module")
def fine24(fine24_value):
    return regular(24), fine24_value.mesh


def test_p2_count_matches_paper_with_24_segments(fine24):
    """Reading 'nodes' as P2 nodes: 24 outline segments, h = outline edge."""
    s = meshing.mesh_stats(fine24[1])
    assert abs(s.n_p2_nodes - PAPER_FINE_NODES) <= 0.15 * PAPER_FINE_NODES


def test_vertex_count_matches_paper_with_48_segments():
    """Reading 'nodes' as vertices: the same count needs 48 outline segments."""
    s = meshing.mesh_stats(meshing.uniform_mesh(BOX, [regular(48)]))
    assert abs(s.n_vertices - PAPER_FINE_NODES) <= 0.15 * PAPER_FINE_NODES


def test_mean_edge_is_h_and_quality(fine24, fine24_value):
    disk, mesh = fine24
    h = 2 * 0.5e-3 * np.sin(np.pi / 24)
    L = edge_lengths(mesh)
    assert abs(L.mean() / h - 1.0) <= 0.1
    s = meshing.mesh_stats(mesh)
    assert s.min_angle >= 30.0 - 1e-9
    assert s.max_aspect <= 3.0 and s.n_inverted == 0
    np.testing.assert_array_equal(mesh.p[:, fine24_value.particle_nodes[0]], disk)


def test_boundaries_follow_segment_markers(fine24):
    disk, mesh = fine24
    b = mesh.boundaries
    assert set(b) == {"wall", "left", "right", "bottom", "top", "particle0"}
    h = 2 * 0.5e-3 * np.sin(np.pi / 24)
    assert b["left"].size == round(11e-3 / h) and b["bottom"].size == round(3e-3 / h)
    assert b["particle0"].size == 24
    np.testing.assert_array_equal(np.sort(mesh.boundary_facets()),
                                  np.sort(np.concatenate([b["wall"], b["particle0"]])))
    np.testing.assert_array_equal(mesh.p[0, mesh.facets[:, b["right"]]], 3e-3)


def test_explicit_h_scales_the_count():
    coarse = meshing.mesh_stats(meshing.uniform_mesh(BOX, [regular(24)], h=0.26e-3))
    fine = meshing.mesh_stats(meshing.uniform_mesh(BOX, [regular(24)], h=0.13e-3))
    # vertex count ~ area / h^2: halving h quadruples it (boundary effects aside)
    assert 3.3 <= fine.n_vertices / coarse.n_vertices <= 4.3


def test_empty_domain_and_polygonal_domain():
    mesh = meshing.uniform_mesh((0.0, 0.0, 1.0, 1.0), [], h=0.1)
    assert set(mesh.boundaries) == {"wall", "left", "right", "bottom", "top"}
    tri = regular(3, 1.0, (0.0, 0.0), 0.2)
    mesh = meshing.uniform_mesh(tri, [regular(12, 0.1, (0.0, 0.0))], h=0.05)
    assert set(mesh.boundaries) == {"wall", "particle0"}
    assert np.all(geometry.edge_distance(tri, mesh.p)[0] >= -1e-12)
    assert meshing.mesh_stats(mesh).min_angle >= 30.0 - 1e-9


def test_deterministic():
    a = meshing.uniform_mesh(BOX, [regular(24, rot=0.1)])
    b = meshing.uniform_mesh(BOX, [regular(24, rot=0.1)])
    np.testing.assert_array_equal(a.p, b.p)
    np.testing.assert_array_equal(a.t, b.t)
