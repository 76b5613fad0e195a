"""Contact geometry: overlap area, centroid, intersection chord (dem.overlap)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from skfem_granular.dem import Polygon, overlap_numba
from skfem_granular.dem.overlap import EPS_PARALLEL, contact_normals, overlap_geometry
from skfem_granular.dem.particles import pad_outlines

BACKENDS = ["numpy"] + (["numba"] if overlap_numba.AVAILABLE else [])


def geometry(A, B, backend="numpy"):
    """Overlap of single polygons A, B ((2, n) arrays) with the chosen backend."""
    V, count = pad_outlines([np.asarray(A, float), np.asarray(B, float)])
    if backend == "numba":
        g = overlap_numba.overlap_pairs_numba(V, count, np.array([0]), np.array([1]))
    else:
        g = overlap_geometry(V[:1], V[1:])
    return g


def square(x, y, s):
    return Polygon.rectangle(x, y, x + s, y + s).vertices


@pytest.mark.parametrize("backend", BACKENDS)
def test_two_squares_corner_overlap(backend):
    # unit squares, second shifted by (0.5, 0.5): overlap [0.5, 1]^2,
    # area 0.25, centroid (0.75, 0.75); outlines cross at (1, 0.5) and (0.5, 1)
    g = geometry(square(0, 0, 1), square(0.5, 0.5, 1), backend)
    assert g.area[0] == pytest.approx(0.25, rel=1e-14)
    np.testing.assert_allclose(g.centroid[:, 0], [0.75, 0.75], rtol=1e-14)
    assert g.ncross[0] == 4  # two crossings, each found from both outlines
    assert g.length[0] == pytest.approx(np.sqrt(0.5), rel=1e-14)
    assert abs(g.chord[0, 0] * g.chord[1, 0]) == pytest.approx(0.5, rel=1e-12)  # 45 deg
    n = contact_normals(g, np.array([[0.5], [0.5]]), np.array([[1.0], [1.0]]))
    np.testing.assert_allclose(n[:, 0], [np.sqrt(0.5), np.sqrt(0.5)], rtol=1e-12)


@pytest.mark.parametrize("backend", BACKENDS)
def test_aligned_squares_side_by_side_collinear_edges(backend):
    # same height, overlap strip [1 - d, 1] x [0, 1]: area d, centroid (1 - d/2, 1/2);
    # collinear top/bottom edges: the chord must be vertical (normal along x)
    d = 0.1
    g = geometry(square(0, 0, 1), square(1 - d, 0, 1), backend)
    assert g.area[0] == pytest.approx(d, rel=1e-13)
    np.testing.assert_allclose(g.centroid[:, 0], [1 - d / 2, 0.5], rtol=1e-13)
    assert g.length[0] == pytest.approx(1.0, rel=1e-13)
    n = contact_normals(g, np.array([[0.5], [0.5]]), np.array([[1.4], [0.5]]))
    np.testing.assert_allclose(n[:, 0], [1.0, 0.0], atol=1e-13)


@pytest.mark.parametrize("backend", BACKENDS)
def test_triangle_corner_in_square(backend):
    # triangle (0.5,-0.2), (0.9,0.3), (0.5,0.3) poking into the unit square through y = 0:
    # inside part is the trapezoid 0 <= y <= 0.3, 0.5 <= x <= 0.5 + 0.8 (y + 0.2):
    # area = int_0^0.3 0.8 (y + 0.2) dy = 0.084;
    # x-moment = int 0.5 w + 0.5 w^2 dy, y-moment = int y w dy with w = 0.8 (y + 0.2)
    T = np.array([[0.5, 0.9, 0.5], [-0.2, 0.3, 0.3]])
    g = geometry(square(0, 0, 1), T, backend)
    y = np.linspace(0, 0.3, 200001)
    w = 0.8 * (y + 0.2)
    area = 0.084
    mx = np.trapezoid(0.5 * w + 0.5 * w * w, y)
    my = np.trapezoid(y * w, y)
    assert g.area[0] == pytest.approx(area, rel=1e-14)
    np.testing.assert_allclose(g.centroid[:, 0], [mx / area, my / area], rtol=1e-9)
    # the outlines cross at (0.5, 0) and (0.66, 0): chord along x, length 0.16
    assert g.length[0] == pytest.approx(0.16, rel=1e-13)
    assert abs(g.chord[1, 0]) < 1e-14


@pytest.mark.parametrize("backend", BACKENDS)
def test_apart_touching_and_contained(backend):
    assert geometry(square(0, 0, 1), square(2, 0, 1), backend).area[0] == 0.0
    assert geometry(square(0, 0, 1), square(1, 0.3, 1), backend).area[0] == 0.0  # touching
    g = geometry(square(0, 0, 1), square(0.2, 0.3, 0.5), backend)  # contained
    assert g.area[0] == pytest.approx(0.25, rel=1e-14)
    np.testing.assert_allclose(g.centroid[:, 0], [0.45, 0.55], rtol=1e-14)
    assert g.ncross[0] == 0


polygons = st.builds(
    lambda n, r, x, y, a: Polygon.regular(n, r, center=(x, y), angle=a).vertices,
    st.integers(3, 12), st.floats(0.2, 1.0), st.floats(-1.0, 1.0), st.floats(-1.0, 1.0),
    st.floats(0.0, 2 * np.pi),
)


@settings(max_examples=150, deadline=None)
@given(polygons, polygons)
def test_overlap_properties(A, B):
    """Symmetric, bounded by the smaller area, zero when bounding circles are apart,
    centroid inside both, both backends agree.

    Edges within EPS_PARALLEL of collinear are snapped to collinear, which moves
    the area by at most ~EPS_PARALLEL * scale^2: that is the agreement bound for
    swapped arguments and the two backends (scale ~ 2 here)."""
    g1, g2 = geometry(A, B), geometry(B, A)
    a = g1.area[0]
    snap = 10 * EPS_PARALLEL * 2.0**2
    assert a == pytest.approx(g2.area[0], rel=1e-10, abs=snap)
    areas = [Polygon(A).area, Polygon(B).area]
    assert 0.0 <= a <= min(areas) * (1 + 1e-12)
    cA, cB = Polygon(A).centroid, Polygon(B).centroid
    rA, rB = Polygon(A).bounding_radius, Polygon(B).bounding_radius
    if np.hypot(*(cA - cB)) > rA + rB:
        assert a == 0.0
    # snapping moves area <= snap anywhere within the diameter (<= 4): the centroid by up
    # to snap 4 / a (hypothesis found a regular polygon against a near-copy of itself whose
    # centroids came out 1.2e-10 apart)
    c_tol = 1e-10 + snap * 4.0 / max(a, 1e-300)
    if a > 1e-8:
        np.testing.assert_allclose(g1.centroid, g2.centroid, atol=c_tol)
        for P in (A, B):  # centroid of a convex overlap lies inside both polygons
            e = np.roll(P, -1, axis=1) - P
            d = g1.centroid - P
            assert np.all(e[0] * d[1] - e[1] * d[0] >= -1e-12)
    if overlap_numba.AVAILABLE:
        gn = geometry(A, B, "numba")
        assert gn.area[0] == pytest.approx(a, rel=1e-10, abs=snap)
        if a > 1e-8:
            np.testing.assert_allclose(gn.centroid, g1.centroid, atol=c_tol)


@settings(max_examples=60, deadline=None)
@given(polygons, st.floats(0.0, 2 * np.pi), st.floats(0.05, 0.5))
def test_overlap_with_half_plane_wall_against_clipped_polygon(A, phi, depth):
    """Area of a polygon cut by a half-plane wall equals the clipped-polygon area."""
    P = Polygon(A)
    n = np.array([np.cos(phi), np.sin(phi)])
    # wall: large square whose face is the line n.x = h, with the wall on the side n.x > h
    h = (P.vertices.T @ n).max() - depth * P.bounding_radius
    t = np.array([-n[1], n[0]])
    L = 10.0
    c0 = n * h
    W = Polygon(np.column_stack([c0 - L * t, c0 - L * t + L * n, c0 + L * t + L * n,
                                 c0 + L * t])).vertices
    g = geometry(A, W)
    # reference: shoelace of the polygon clipped by the half-plane (Sutherland-Hodgman)
    pts = []
    V = P.vertices.T
    for k in range(len(V)):
        p, q = V[k], V[(k + 1) % len(V)]
        sp, sq = p @ n - h, q @ n - h
        if sp >= 0:
            pts.append(p)
        if sp * sq < 0:
            pts.append(p + (q - p) * sp / (sp - sq))
    pts = np.array(pts)
    ref = 0.5 * abs(np.sum(pts[:, 0] * np.roll(pts[:, 1], -1) - np.roll(pts[:, 0], -1) * pts[:, 1]))
    assert g.area[0] == pytest.approx(ref, rel=1e-10)
    # the chord lies on the wall face: normal parallel to n
    assert abs(g.chord[:, 0] @ n) < 1e-9
