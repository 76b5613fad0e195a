"""Conversion of a triangulation to ``skfem.MeshTri`` with named boundaries.

Boundaries come from the segment markers ``triangle`` returns (every domain
edge and particle outline carries its own marker), never from geometric tests
on facet midpoints: on a polygonal hole the midpoints lie inside the
circumscribed circle, so a radius test misses them.
"""

from __future__ import annotations

import numpy as np
import skfem
from numpy.typing import NDArray

from .pslg import Layout, Triangulation, boundary_labels
from .value import BodyFittedMesh, Recipe


def to_body_fitted(tri: Triangulation, layout: Layout, recipe: Recipe | None = None,
                   subdomains: dict[str, NDArray[np.bool_]] | None = None,
                   outline_vertices: list[NDArray[np.int64]] | None = None) -> BodyFittedMesh:
    """Build a ``skfem.MeshTri`` from a triangulation, with its provenance.

    Unused nodes (duplicates ``triangle`` skipped) are dropped. The mesh gets
    ``boundaries`` ``"wall"`` (plus ``"bottom"``, ``"right"``, ``"top"``,
    ``"left"`` for a rectangle) and ``"particle0"``, ... , and optional
    ``subdomains`` (boolean masks over triangles). Returned as a
    :class:`~meshing.value.BodyFittedMesh` with ``recipe`` and the particles'
    outline vertex indices (``particle_nodes``, in outline order). When the
    layout's outlines carry extra nodes on their edges (a field mesh's gaps),
    ``outline_vertices[k]`` gives the positions of particle ``k``'s own vertices
    in its layout outline, and only those are ``particle_nodes``.
    """
    used = np.zeros(tri.points.shape[1], dtype=bool)
    used[tri.t.ravel()] = True
    new = np.cumsum(used) - 1
    p = np.ascontiguousarray(tri.points[:, used])
    t = np.ascontiguousarray(new[tri.t].astype(np.int32))
    mesh = skfem.MeshTri(p, t, sort_t=False)
    nv = p.shape[1]
    f = np.sort(mesh.facets, axis=0).astype(np.int64)
    fkey = f[0] * nv + f[1]
    order = np.argsort(fkey)
    seg = np.sort(new[tri.segments], axis=0)
    skey = seg[0] * nv + seg[1]
    pos = np.searchsorted(fkey, skey, sorter=order)
    facet = order[np.clip(pos, 0, fkey.size - 1)]
    if np.any(fkey[facet] != skey):
        raise RuntimeError("a constraint segment is not a mesh edge")
    bnd: dict[str, list[NDArray]] = {}
    for m, labels in enumerate(boundary_labels(layout), start=2):
        for name in labels:
            bnd.setdefault(name, []).append(facet[tri.markers == m])
    boundaries = {k: np.sort(np.concatenate(v)).astype(np.int64) for k, v in bnd.items()}
    subs = None
    if subdomains:
        subs = {k: np.flatnonzero(v).astype(np.int64) for k, v in subdomains.items()}
    mesh = skfem.MeshTri(p, t, _boundaries=boundaries, _subdomains=subs, sort_t=False)
    off = layout.n_wall
    nodes = []
    for k, P in enumerate(layout.particles):
        own = np.arange(P.shape[1]) if outline_vertices is None else outline_vertices[k]
        nodes.append(new[off + own])
        off += P.shape[1]
    return BodyFittedMesh(mesh=mesh, recipe=recipe, particle_nodes=tuple(nodes))
