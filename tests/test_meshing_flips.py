"""Edge flips of a moving mesh (meshing.flips): valid triangulations, judged over motions."""

from __future__ import annotations

import numpy as np
import pytest
import skfem
from scipy.spatial import Delaunay

from meshing.flips import flip_repair, with_triangles
from meshing.quality import angles, signed_areas


def _disk(jitter: float, seed: int = 3):
    """A disk mesh (1024 triangles) and its interior vertices moved by ``jitter``."""
    m = skfem.MeshTri.init_circle(4)
    rng = np.random.default_rng(seed)
    p = m.p.copy()
    inner = np.setdiff1d(np.arange(p.shape[1]), m.boundary_nodes())
    p[:, inner] += jitter * rng.standard_normal((2, inner.size))
    return m, p


def _worst(configs, t):
    """Smallest angle of each triangle over the configurations; -1 where one turned over."""
    sign = np.sign(signed_areas(configs[0], t))
    out = np.full(t.shape[1], np.inf)
    for p in configs:
        flat = signed_areas(p, t) * sign <= 0
        out = np.minimum(out, np.where(flat, -1.0, angles(p, t).min(axis=0)))
    return out


def test_flipping_every_triangle_reaches_the_delaunay_triangulation():
    """With every triangle below the bound, the flips are Lawson's: the max-min-angle
    (Delaunay) triangulation of the vertices, the same smallest angle of every triangle
    as scipy's Delaunay triangulation of the points."""
    m, p = _disk(0.008)
    t, changed = flip_repair(m.t, [p], 61.0, max_flips=100_000)
    ours = np.sort(angles(p, t).min(axis=0))
    ref = np.sort(angles(p, Delaunay(p.T).simplices.T).min(axis=0))
    assert changed.size > 100
    assert ours == pytest.approx(ref, abs=1e-9)


def test_flips_keep_every_configuration_valid_and_only_raise_angles():
    """Judged over two configurations, no triangle turns over in either, the smallest
    angle over both never drops, fewer triangles stay below the bound, and the repaired
    mesh tiles the same domain with the same boundary edges."""
    m, p = _disk(0.008, seed=1)
    _, q = _disk(0.008, seed=2)
    before = _worst([p, q], m.t)
    t, changed = flip_repair(m.t, [p, q], 25.0)
    after = _worst([p, q], t)
    assert changed.size > 0 and after.min() >= 0.0
    assert after.min() >= before.min()
    assert (after < 25.0).sum() < (before < 25.0).sum()
    unchanged = np.setdiff1d(np.arange(t.shape[1]), changed)
    assert np.array_equal(t[:, unchanged], m.t[:, unchanged])
    for x in (p, q):
        assert abs(signed_areas(x, t)).sum() == pytest.approx(abs(signed_areas(x, m.t)).sum(),
                                                               rel=1e-12)
    new = with_triangles(m.with_boundaries({"rim": m.boundary_facets()}), t, p=q)
    assert new.facets.shape == m.facets.shape  # the same edge count: a triangulation
    rim = np.sort(new.facets[:, new.boundaries["rim"]], axis=0)
    assert set(map(tuple, rim.T)) == set(map(tuple, np.sort(m.facets[:, m.boundary_facets()],
                                                            axis=0).T))


def test_a_mesh_already_above_the_bound_is_returned_unchanged():
    m, p = _disk(0.0)
    t, changed = flip_repair(m.t, [p], 10.0)
    assert changed.size == 0 and np.array_equal(t, m.t)


def test_configurations_of_the_wrong_shape_are_refused():
    m, p = _disk(0.0)
    with pytest.raises(ValueError, match=r"^configurations: must be \(2, nv\)"):
        flip_repair(m.t, [p[:, :10]], 20.0)


def test_the_near_configurations_come_first():
    """A configuration far ahead (interior moved 2 % of the radius) judged beside the
    present one (0.6 %): over both at once, flips that help the far one spoil the
    present one (its smallest angle from 20.6 / 19.5 / 22.7 degrees down to 3.0 / 4.0 /
    0.7); with the present one first, its smallest angle never drops (measured 21.9 /
    25.1 / 24.2)."""
    for seed in range(3):
        m, now = _disk(0.006, seed)
        _, far = _disk(0.02, seed + 100)
        before = angles(now, m.t).min()
        t_all, _ = flip_repair(m.t, [now, far], 25.0)
        t_near, changed = flip_repair(m.t, [now, far], 25.0, near=1)
        assert changed.size > 0
        assert angles(now, t_near).min() >= before
        assert angles(now, t_all).min() < before - 10.0
