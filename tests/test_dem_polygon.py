"""Polygon geometry and validation (skfem_granular.dem.polygon)."""

import numpy as np
import pytest

from skfem_granular.dem import Particle, Polygon
from skfem_granular.dem.particles import ParticleArrays


def test_rectangle_area_centroid_second_moment():
    # rectangle a x b: A = ab, J = ab (a^2 + b^2) / 12
    a, b = 2.0, 0.5
    P = Polygon.rectangle(1.0, 3.0, 1.0 + a, 3.0 + b)
    assert P.area == pytest.approx(a * b, rel=1e-14)
    np.testing.assert_allclose(P.centroid, [2.0, 3.25], rtol=1e-14)
    assert P.second_moment == pytest.approx(a * b * (a * a + b * b) / 12.0, rel=1e-13)


@pytest.mark.parametrize("n", [3, 6, 24, 200])
def test_regular_polygon_properties(n):
    # regular n-gon, circumradius R: A = n R^2 sin(2 pi/n)/2,
    # J = A R^2 (1 + 2 cos^2(pi/n)) / 6  (polar moment about the centre)
    R = 0.7
    P = Polygon.regular(n, R, center=(0.3, -0.2), angle=0.1)
    A = 0.5 * n * R * R * np.sin(2 * np.pi / n)
    assert P.area == pytest.approx(A, rel=1e-12)
    np.testing.assert_allclose(P.centroid, [0.3, -0.2], atol=1e-14)
    J = A * R * R * (1 + 2 * np.cos(np.pi / n) ** 2) / 6
    assert P.second_moment == pytest.approx(J, rel=1e-12)
    assert P.bounding_radius == pytest.approx(R, rel=1e-14)


def test_many_sided_polygon_tends_to_disk():
    P = Polygon.regular(2000, 1.0)
    assert P.area == pytest.approx(np.pi, rel=1e-5)
    assert P.second_moment == pytest.approx(np.pi / 2, rel=1e-5)


def test_core_by_ratio_and_offset():
    P = Polygon.rectangle(0, 0, 2, 1)
    C = P.core(ratio=0.8)
    assert C.area == pytest.approx(0.64 * P.area, rel=1e-14)
    np.testing.assert_allclose(C.centroid, P.centroid, atol=1e-15)
    O = P.core(offset=0.1)
    np.testing.assert_allclose(O.vertices, [[0.1, 1.9, 1.9, 0.1], [0.1, 0.1, 0.9, 0.9]],
                               atol=1e-14)
    assert P.core(ratio=1.0).area == P.area
    with pytest.raises(ValueError, match="core offset = 0.6: too large"):
        P.core(offset=0.6)
    with pytest.raises(ValueError, match=r"core ratio = 1.5: must be in \(0, 1\]"):
        P.core(ratio=1.5)


@pytest.mark.parametrize(
    ("vertices", "match"),
    [
        ([[0, 0, 1, 1], [0, 1, 1, 0]], "signed area .*: must be > 0"),  # clockwise
        ([[0, 2, 1, 2, 0], [0, 0, 0.5, 1, 1]], "must be strictly convex"),  # dent
        ([[0, 1, 2], [0, 1, 2]], "must be > 0"),  # collinear
        ([[0, 1, np.nan], [0, 0, 1]], r"vertices\[:, 2\] .*must be finite"),
        ([[0, 1], [0, 1]], "must be \\(2, N\\) with N >= 3"),
        ([[0, 1, 1, 1], [0, 0, 0, 1]], "coincide"),
    ],
)
def test_bad_outlines_name_field_and_range(vertices, match):
    with pytest.raises(ValueError, match=match):
        Polygon(vertices, name="particles[3]")


def test_bad_density_names_particle():
    parts = [Particle(Polygon.regular(6, 1.0), 1.0), Particle(Polygon.regular(6, 1.0), -1.0)]
    with pytest.raises(ValueError, match=r"particles\[1\]\.density = -1\.0: must be"):
        ParticleArrays(parts)
    for bad in (0.0, np.nan, "x"):
        with pytest.raises(ValueError, match=r"particles\[0\]\.density"):
            ParticleArrays([Particle(Polygon.regular(6, 1.0), bad)])


def test_particle_arrays_mass_inertia_and_outlines():
    P = Polygon.regular(8, 2.0, center=(1.0, 1.0), angle=0.3)
    pa = ParticleArrays([Particle(P, 3.0, core_ratio=0.5),
                         Particle(Polygon.rectangle(0, 0, 1, 2), 2.0, core_offset=0.1)])
    np.testing.assert_allclose(pa.mass, [3.0 * P.area, 4.0], rtol=1e-14)
    assert pa.inertia[1] == pytest.approx(2.0 * 2.0 * (1 + 4) / 12, rel=1e-13)
    np.testing.assert_allclose(pa.q[:, 0], [1.0, 1.0, 0.0], atol=1e-14)
    W = pa.world_shadows()
    np.testing.assert_allclose(W[0].T, P.vertices, atol=1e-14)
    # padded with the first vertex
    np.testing.assert_allclose(W[1, 4:], np.repeat(W[1, :1], 4, axis=0))
    C = pa.world_cores()
    np.testing.assert_allclose(C[0].T, P.scaled(0.5).vertices, atol=1e-14)
