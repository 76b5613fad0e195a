"""Moving particles, the remeshing trigger, remeshing, plotting, provenance."""

import dataclasses

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
    return meshing.build("graded", BOX, [regular(24)])


def assert_same(a, b):
    """Two BodyFittedMesh values are the same mesh, bit for bit, built the same way."""
    pairs = [(a.mesh.p, b.mesh.p), (a.mesh.t, b.mesh.t)]
    pairs += zip(a.particle_nodes, b.particle_nodes, strict=True)
    pairs += zip(a.recipe.particles, b.recipe.particles, strict=True)
    for name in ("boundaries", "subdomains"):
        x, y = getattr(a.mesh, name) or {}, getattr(b.mesh, name) or {}
        assert x.keys() == y.keys()
        pairs += [(x[k], y[k]) for k in x]
    for x, y in pairs:
        assert x.dtype == y.dtype
        np.testing.assert_array_equal(x, y)
    assert (a.recipe.kind, a.recipe.domain, a.recipe.options) == (
        b.recipe.kind, b.recipe.domain, b.recipe.options)


def test_small_move_keeps_quality_and_walls(graded):
    new = regular(24, c=(1.5e-3, 5.49e-3), rot=0.02)
    moved = meshing.move_particles(graded, [new])
    np.testing.assert_array_equal(moved.mesh.p[:, moved.particle_nodes[0]], new)
    np.testing.assert_array_equal(moved.mesh.t, graded.mesh.t)
    walls = np.unique(graded.mesh.facets[:, graded.mesh.boundaries["wall"]])
    np.testing.assert_array_equal(moved.mesh.p[:, walls], graded.mesh.p[:, walls])
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
    np.testing.assert_array_equal(fresh.mesh.p[:, fresh.particle_nodes[0]], new)
    assert fresh.recipe.kind == "graded"
    assert abs(s.n_vertices - s0.n_vertices) <= 0.1 * s0.n_vertices
    assert set(fresh.mesh.boundaries) == set(graded.mesh.boundaries)


def test_inverted_elements_are_detected(graded):
    p = graded.mesh.p.copy()
    t = graded.mesh.t.copy()
    p[:, t[0, 0]], p[:, t[1, 0]] = graded.mesh.p[:, t[1, 0]], graded.mesh.p[:, t[0, 0]]
    import skfem
    flipped = skfem.MeshTri(p, t, sort_t=False)
    assert meshing.mesh_stats(flipped).n_inverted >= 1
    assert meshing.remesh_needed(flipped)


def test_remesh_keeps_kind_uniform_and_group():
    u = meshing.build("uniform", BOX, [regular(24)], h=0.2e-3)
    u2 = meshing.remesh(u, [regular(24, c=(1.5e-3, 4e-3))])
    assert u2.recipe.kind == "uniform"
    n, n2 = meshing.mesh_stats(u).n_vertices, meshing.mesh_stats(u2).n_vertices
    assert abs(n2 - n) <= 0.05 * n
    parts = [regular(12, 0.2e-3, (1.2e-3, 5e-3)), regular(12, 0.2e-3, (1.8e-3, 5.1e-3))]
    g = meshing.build("group", BOX, parts)
    moved = [p + np.array([[0.0], [-0.5e-3]]) for p in parts]
    g2 = meshing.remesh(g, moved)
    assert g2.recipe.kind == "group" and set(g2.mesh.subdomains) == {"fine", "graded"}
    assert meshing.mesh_stats(g2).min_angle >= 20.0


def test_plot_mesh_colours_named_boundaries(graded):
    ax = meshing.plot_mesh(graded)
    labels = sorted(c.get_label() for c in ax.collections
                    if c.get_label() in graded.mesh.boundaries)
    assert labels == ["bottom", "left", "particle0", "right", "top"]
    import matplotlib.pyplot as plt
    plt.close(ax.figure)


def test_provenance_lives_beside_the_mesh_and_survives_skfem_transforms(graded):
    disk, moved = regular(24), regular(24, c=(1.5e-3, 4.5e-3), rot=0.3)
    plain = meshing.graded_mesh(BOX, [disk])
    for m in (plain, graded.mesh):
        assert not hasattr(m, "particle_nodes") and not hasattr(m, "meshing_recipe")
    assert_same(graded, dataclasses.replace(graded, mesh=plain))   # builder = build(...).mesh
    np.testing.assert_array_equal(graded.mesh.p[:, graded.particle_nodes[0]], disk)
    # a scikit-fem transform returns a new mesh; the value keeps its provenance
    tagged = dataclasses.replace(
        graded, mesh=graded.mesh.with_boundaries({"low": lambda x: x[1] < 1e-3}))
    assert {"low", "particle0"} <= set(tagged.mesh.boundaries)
    assert tagged.recipe is graded.recipe
    np.testing.assert_array_equal(tagged.mesh.p[:, tagged.particle_nodes[0]], disk)
    fresh = meshing.build("graded", BOX, [moved], **graded.recipe.options)
    assert_same(meshing.remesh(tagged, [moved]), fresh)
    assert_same(meshing.remesh(meshing.move_particles(tagged, [moved]), [moved]), fresh)
    assert_same(graded.recipe.build(), graded)
    assert_same(fresh.recipe.build(), fresh)
