"""Moving particles in an existing mesh, and rebuilding a mesh for moved particles.

Both work on a :class:`meshing.BodyFittedMesh` (from :func:`meshing.build`,
or from :func:`remesh` and :func:`move_particles` themselves), whose recipe
and particle nodes say how the mesh was built and where the particles are.
Typical loop (the paper's Section 4: move, check, relax and re-triangulate)::

    value = meshing.build("graded", domain, outlines)
    ...
    moved = meshing.move_particles(value, new_outlines)
    if meshing.remesh_needed(moved):
        value = meshing.remesh(value, new_outlines)   # same kind, options, quality
    else:
        value = moved
    mesh = value.mesh
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import skfem
from numpy.typing import NDArray

from .geometry import (
    as_particles,
    centroid,
    edge_distance,
    outline_lengths,
    project_to_edge,
    subdivide,
)
from .registry import build
from .value import BodyFittedMesh, Recipe


def _recipe(mesh: object) -> Recipe:
    """The recipe of a :class:`BodyFittedMesh`; ValueError for anything else."""
    if isinstance(mesh, BodyFittedMesh):
        if mesh.recipe is not None:
            return mesh.recipe
        got = "a BodyFittedMesh with recipe None"
    elif isinstance(mesh, skfem.Mesh):
        got = f"a bare skfem.{type(mesh).__name__}"
    else:
        got = f"{type(mesh).__name__}"
    raise ValueError(f"mesh: has no meshing_recipe (got {got}; pass a BodyFittedMesh from "
                     "meshing.build, remesh or move_particles)")


def _outlines(recipe: Recipe, particles: object) -> list[NDArray[np.float64]]:
    new = as_particles(particles)
    if len(new) != len(recipe.particles):
        raise ValueError(f"particles: expected {len(recipe.particles)} outlines (as in the "
                         f"mesh), got {len(new)}")
    return new


def remesh(mesh: BodyFittedMesh, particles: object, **changes) -> BodyFittedMesh:
    """Build a new mesh of the same kind and options for moved particles.

    Parameters
    ----------
    mesh
        A :class:`meshing.BodyFittedMesh` from :func:`meshing.build` (or from
        this function or :func:`meshing.move_particles`); its ``recipe``
        records domain, kind and options.
    particles
        The particles' new outlines (same number as in ``mesh``), moved
        and/or rotated; validated like the builders' input.
    **changes
        Builder options to override (e.g. ``sigma=1.3``).

    Returns
    -------
    BodyFittedMesh
        ``meshing.build(kind, domain, particles, **options)`` with the
        recipe's kind, domain and options (updated by ``changes``): the same
        construction, so the same quality bounds and boundary names; the node
        set is new (interpolate fields onto it).
    """
    recipe = _recipe(mesh)
    new = _outlines(recipe, particles)
    options = {**recipe.options, **changes}
    return build(recipe.kind, recipe.domain, new, **options)


def rigid_fit(old: NDArray[np.float64], new: NDArray[np.float64]
              ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Least-squares rotation ``R`` and centroids ``(c_old, c_new)`` with
    ``new ~ R (old - c_old) + c_new`` (Kabsch in 2D)."""
    co, cn = old.mean(axis=1), new.mean(axis=1)
    a, b = old - co[:, None], new - cn[:, None]
    ang = np.arctan2(np.sum(a[0] * b[1] - a[1] * b[0]), np.sum(a * b))
    R = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
    return R, co, cn


def move_particles(mesh: BodyFittedMesh, particles: object,
                   falloff: float | Sequence[float] | None = None) -> BodyFittedMesh:
    """Move particle outline nodes to new outlines, dragging nearby nodes along.

    The particle nodes are placed exactly at the new (subdivided) outline
    vertices, nodes a field mesh added on an outline edge (in a narrow gap) at
    the same fraction of the moved edge. Interior nodes follow each particle's
    best-fit rigid motion, weighted by ``w = (1 - d / falloff)^2`` for a
    distance ``d`` from the old outline (``w = 0`` beyond ``falloff``); wall
    nodes never move. Connectivity is kept, so elements may degrade or invert:
    check with :func:`meshing.remesh_needed`.

    Parameters
    ----------
    mesh
        A :class:`meshing.BodyFittedMesh` with a recipe (from
        :func:`meshing.build`, :func:`meshing.remesh` or this function).
    particles
        New outlines, the same number and (after subdivision by the mesh's
        ``delta_l``) the same vertex counts as the mesh's particles.
    falloff
        Distance over which interior nodes follow, ``> 0``, one per particle
        or one for all; default twice each particle's circumradius.

    Returns
    -------
    BodyFittedMesh
        Same connectivity, boundaries, subdomains and ``particle_nodes``;
        ``recipe`` updated with the new outlines.
    """
    recipe = _recipe(mesh)
    nodes = mesh.particle_nodes
    skmesh = mesh.mesh
    new = _outlines(recipe, particles)
    new = [subdivide(P, recipe.options.get("delta_l")) for P in new]
    p = np.array(skmesh.p, dtype=np.float64)
    q = p.copy()
    fall = np.broadcast_to(np.asarray(np.nan if falloff is None else falloff, dtype=float),
                           (len(new),))
    boundary = np.zeros(p.shape[1], dtype=bool)
    boundary[np.unique(skmesh.facets[:, skmesh.boundary_facets()])] = True
    weight = np.zeros(p.shape[1])
    shift = np.zeros_like(p)
    for k, (idx, P) in enumerate(zip(nodes, new, strict=True)):
        if P.shape[1] != idx.size:
            raise ValueError(f"particles[{k}]: expected {idx.size} vertices (after delta_l "
                             f"subdivision) as in the mesh, got {P.shape[1]}")
        old = p[:, idx]
        R, co, cn = rigid_fit(old, P)
        r = float(np.max(np.hypot(*(old - centroid(old)[:, None]))))
        f = 2.0 * r if np.isnan(fall[k]) else float(fall[k])
        if not f > 0.0:
            raise ValueError(f"falloff: must be > 0, got {f!r}")
        d = np.maximum(np.hypot(*(p - co[:, None])) - r, 0.0)
        w = np.clip(1.0 - d / f, 0.0, 1.0) ** 2
        w[boundary] = 0.0
        weight += w
        shift += w * (R @ (p - co[:, None]) + cn[:, None] - p)
        q[:, idx] = P
    scale = np.where(weight > 1.0, 1.0 / np.maximum(weight, 1e-300), 1.0)
    free = ~boundary
    q[:, free] += (shift * scale)[:, free]
    for k, (idx, P) in enumerate(zip(nodes, new, strict=True)):
        q[:, idx] = P
        on = np.unique(skmesh.facets[:, skmesh.boundaries[f"particle{k}"]])
        extra = np.setdiff1d(on, idx)
        if extra.size:      # nodes on the old edges: same fraction of the new edge
            old = p[:, idx]
            _, e = edge_distance(old, p[:, extra])
            frac = project_to_edge(old, e, p[:, extra]) / outline_lengths(old)[e]
            q[:, extra] = P[:, e] + frac * (np.roll(P, -1, axis=1)[:, e] - P[:, e])
    moved = skfem.MeshTri(q, np.asarray(skmesh.t), _boundaries=skmesh._boundaries,
                          _subdomains=skmesh._subdomains, sort_t=False)
    return BodyFittedMesh(mesh=moved, recipe=replace(recipe, particles=tuple(new)),
                          particle_nodes=nodes)
