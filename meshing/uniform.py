"""Equidistant ("fine") meshes: quality constrained Delaunay with a size bound."""

from __future__ import annotations

import numpy as np
import skfem
from numpy.typing import NDArray

from .geometry import MAX_ELEMENTS
from .inputs import prepare
from .pslg import Layout, fixed_point, triangulate
from .registry import builds
from .skfem_mesh import to_body_fitted
from .value import BodyFittedMesh, Recipe

AREA_FACTOR = 1.5
"""Area bound over the equilateral area ``sqrt(3)/4 h**2``. ``triangle`` keeps
every area below the bound, so the mean area is smaller; with 1.5 the mean
edge length comes out within a few percent of ``h`` (measured on the paper's
box: 1.01 h)."""

MIN_ANGLE = 30.0
"""Minimum angle (degrees) requested from ``triangle``."""


def split_walls(D: NDArray[np.float64], h: float) -> tuple[NDArray, NDArray]:
    """Domain corners followed by nodes splitting each edge into pieces of about ``h``.

    Returns ``(points (2, n), edge index (n,))``.
    """
    nd = D.shape[1]
    E = np.roll(D, -1, axis=1) - D
    L = np.hypot(*E)
    pts, edges = [D], [np.arange(nd)]
    for j in range(nd):
        n = max(1, int(np.rint(L[j] / h)))
        s = np.arange(1, n) / n
        pts.append(D[:, j:j + 1] + s * E[:, j:j + 1])
        edges.append(np.full(s.size, j))
    return np.hstack(pts), np.concatenate(edges)


def uniform_mesh(domain: object = (0.0, 0.0, 3e-3, 11e-3), particles: object = (),
                 h: float | None = None, delta_l: float | None = None, *,
                 min_angle: float = MIN_ANGLE) -> skfem.MeshTri:
    """Equidistant triangle mesh of a domain with particle holes.

    Parameters
    ----------
    domain
        ``(x0, y0, x1, y1)`` rectangle or a convex counter-clockwise
        ``(2, N)`` outline.
    particles
        List of convex counter-clockwise ``(2, N)`` outlines (or objects with
        ``.vertices``), disjoint and strictly inside the domain; may be empty.
    h
        Target mean edge length, ``0 < h <=`` half the domain's shorter
        bounding-box side. Default: the particles' mean outline edge length
        (after ``delta_l``), which is the paper's "same resolution" fine mesh.
    delta_l
        Outline resolution as in :func:`meshing.graded_mesh`.
    min_angle
        Minimum angle requested from ``triangle``, ``0 < min_angle <= 33``.

    Returns
    -------
    skfem.MeshTri
        Named boundaries as in :func:`meshing.graded_mesh`. Particle outline
        nodes and domain edges are not split (``triangle``'s ``Y`` switch), so
        outline nodes are exactly the given (subdivided) vertices.
        ``meshing.build("uniform", domain, particles, ...)`` returns the same
        mesh as a :class:`meshing.BodyFittedMesh`.
    """
    return build_uniform(domain, particles, h=h, delta_l=delta_l, min_angle=min_angle).mesh


@builds("uniform")
def build_uniform(domain: object, particles: object, *, h: float | None = None,
                  delta_l: float | None = None, min_angle: float = MIN_ANGLE
                  ) -> BodyFittedMesh:
    """:func:`uniform_mesh` as a :class:`~meshing.value.BodyFittedMesh`.

    What :func:`meshing.build` calls for ``kind="uniform"``; the arguments and
    the mesh are those of :func:`uniform_mesh`.
    """
    D, names, outlines = prepare(domain, particles, delta_l)
    if not 0.0 < float(min_angle) <= 33.0:
        raise ValueError(f"min_angle: must be in (0, 33] degrees, got {min_angle!r}")
    span = float(np.min(np.ptp(D, axis=1)))
    if h is None:
        if not outlines:
            raise ValueError("h: required when there are no particles (0 < h <= "
                             f"{0.5 * span:.6g})")
        h = float(np.mean(np.hstack([np.hypot(*(np.roll(P, -1, axis=1) - P))
                                     for P in outlines])))
    try:
        h = float(h)
    except (TypeError, ValueError):
        raise ValueError(f"h: expected a number, got {h!r}") from None
    if not (np.isfinite(h) and 0.0 < h <= 0.5 * span):
        raise ValueError(f"h: must be in (0, {0.5 * span:.6g}] (half the domain's shorter "
                         f"side), got {h!r}")
    d_area = 0.5 * abs(float(np.sum(D[0] * np.roll(D[1], -1) - np.roll(D[0], -1) * D[1])))
    n_est = d_area / (np.sqrt(3.0) / 4.0 * h * h)
    if n_est > MAX_ELEMENTS:
        raise ValueError(f"h = {h:.3g}: would make about {n_est:.2g} triangles; must be >= "
                         f"{np.sqrt(d_area / MAX_ELEMENTS / (np.sqrt(3.0) / 4.0)):.3g} "
                         f"(at most {MAX_ELEMENTS:.0e} triangles)")
    wall, wall_edge = split_walls(D, h)
    layout = Layout(domain=D, edge_names=names, particles=outlines, wall=wall,
                    wall_edge=wall_edge, free=np.zeros((2, 0)))
    area = AREA_FACTOR * np.sqrt(3.0) / 4.0 * h * h
    tri = triangulate(layout, f"q{fixed_point(float(min_angle))}Ya{fixed_point(area)}")
    recipe = Recipe("uniform", domain, tuple(outlines),
                    dict(h=h, delta_l=delta_l, min_angle=min_angle))
    return to_body_fitted(tri, layout, recipe)
