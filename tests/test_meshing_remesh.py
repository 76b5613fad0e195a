"""Moving particles, the remeshing trigger, remeshing, plotting."""

import matplotlib
import numpy as np
import pytest

import meshing

matplotlib.use("Agg")

BOX = (0.0, 0.0, 3e-3, 11e-3)


def regular(n, r=0.5e-3, c=(1.5e-3, 5.5e-3), rot=0.0):
    th = rot + 2.0 * np.pi * np.arange(n) / n
    return np.vstack([c[0] + r * np.cos(th), c[1] + r * np.sin(th)])


@pytest.fixture(scope="module")
def graded():
    return meshing.graded_mesh(BOX, [regular(24)])


def test_small_move_keeps_quality_and_walls(graded):
    new = regular(24, c=(1.5e-3, 5.49e-3), rot=0.02)
    moved = meshing.move_particles(graded, [new])
    np.testing.assert_array_equal(moved.p[:, moved.particle_nodes[0]], new)
    np.testing.assert_array_equal(moved.t, graded.t)
    walls = np.unique(graded.facets[:, graded.boundaries["wall"]])
    np.testing.assert_array_equal(moved.p[:, walls], graded.p[:, walls])
    assert not meshing.remesh_needed(moved)
    # a nearby node moves almost rigidly with the particle
    assert meshing.mesh_stats(moved).min_angle >= 20.0


def test_large_move_triggers_and_remesh_restores_quality(graded):
    new = regular(24, c=(1.5e-3, 4.5e-3), rot=0.3)
    moved = meshing.move_particles(graded, [new])
    assert meshing.remesh_needed(moved)
    fresh = meshing.remesh(moved, [new])
    s, s0 = meshing.mesh_stats(fresh), meshing.mesh_stats(graded)
    assert s.min_angle >= 20.0 and s.max_aspect <= 3.0 and s.n_inverted == 0
    np.testing.assert_array_equal(fresh.p[:, fresh.particle_nodes[0]], new)
    assert fresh.meshing_recipe.kind == "graded"
    assert abs(s.n_vertices - s0.n_vertices) <= 0.1 * s0.n_vertices
    assert set(fresh.boundaries) == set(graded.boundaries)


def test_inverted_elements_are_detected(graded):
    p = graded.p.copy()
    t = graded.t.copy()
    p[:, t[0, 0]], p[:, t[1, 0]] = graded.p[:, t[1, 0]], graded.p[:, t[0, 0]]
    import skfem
    flipped = skfem.MeshTri(p, t, sort_t=False)
    assert meshing.mesh_stats(flipped).n_inverted >= 1
    assert meshing.remesh_needed(flipped)


def test_remesh_keeps_kind_uniform_and_group():
    u = meshing.uniform_mesh(BOX, [regular(24)], h=0.2e-3)
    u2 = meshing.remesh(u, [regular(24, c=(1.5e-3, 4e-3))])
    assert u2.meshing_recipe.kind == "uniform"
    n, n2 = meshing.mesh_stats(u).n_vertices, meshing.mesh_stats(u2).n_vertices
    assert abs(n2 - n) <= 0.05 * n
    parts = [regular(12, 0.2e-3, (1.2e-3, 5e-3)), regular(12, 0.2e-3, (1.8e-3, 5.1e-3))]
    g = meshing.group_mesh(BOX, parts)
    moved = [p + np.array([[0.0], [-0.5e-3]]) for p in parts]
    g2 = meshing.remesh(g, moved)
    assert g2.meshing_recipe.kind == "group" and set(g2.subdomains) == {"fine", "graded"}
    assert meshing.mesh_stats(g2).min_angle >= 20.0


def test_plot_mesh_colours_named_boundaries(graded):
    ax = meshing.plot_mesh(graded)
    labels = sorted(c.get_label() for c in ax.collections if c.get_label() in graded.boundaries)
    assert labels == ["bottom", "left", "particle0", "right", "top"]
    import matplotlib.pyplot as plt
    plt.close(ax.figure)
