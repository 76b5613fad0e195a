"""Moving particles in an existing mesh, and rebuilding a mesh for moved particles.

Typical loop (the paper's Section 4: move, check, relax and re-triangulate)::

    moved = meshing.move_particles(mesh, new_outlines)
    if meshing.remesh_needed(moved):
        mesh = meshing.remesh(mesh, new_outlines)   # same kind, options, quality
    else:
        mesh = moved
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import skfem
from numpy.typing import NDArray

from .geometry import as_particles, centroid, subdivide
from .graded import graded_mesh
from .group import group_mesh
from .uniform import uniform_mesh

BUILDERS = {"graded": graded_mesh, "uniform": uniform_mesh, "group": group_mesh}


def _recipe(mesh):
    recipe = getattr(mesh, "meshing_recipe", None)
    if recipe is None:
        raise ValueError("mesh: has no meshing_recipe; pass a mesh made by graded_mesh, "
                         "uniform_mesh, group_mesh, remesh or move_particles")
    return recipe


def _outlines(recipe, particles: object) -> list[NDArray[np.float64]]:
    new = as_particles(particles)
    if len(new) != len(recipe.particles):
        raise ValueError(f"particles: expected {len(recipe.particles)} outlines (as in the "
                         f"mesh), got {len(new)}")
    return new


def remesh(mesh: skfem.MeshTri, particles: object, **changes) -> skfem.MeshTri:
    """Build a new mesh of the same kind and options for moved particles.

    Parameters
    ----------
    mesh
        A mesh made by :func:`meshing.graded_mesh`, :func:`meshing.uniform_mesh`,
        :func:`meshing.group_mesh` (or by this function); its
        ``meshing_recipe`` records domain, kind and options.
    particles
        The particles' new outlines (same number as in ``mesh``), moved
        and/or rotated; validated like the builders' input.
    **changes
        Builder options to override (e.g. ``sigma=1.3``).

    Returns
    -------
    skfem.MeshTri
        A freshly built mesh: the same construction, so the same quality
        bounds and boundary names; the node set is new (interpolate fields
        onto it).
    """
    recipe = _recipe(mesh)
    new = _outlines(recipe, particles)
    options = {**recipe.options, **changes}
    return BUILDERS[recipe.kind](recipe.domain, new, **options)


def rigid_fit(old: NDArray[np.float64], new: NDArray[np.float64]
              ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Least-squares rotation ``R`` and centroids ``(c_old, c_new)`` with
    ``new ~ R (old - c_old) + c_new`` (Kabsch in 2D)."""
    co, cn = old.mean(axis=1), new.mean(axis=1)
    a, b = old - co[:, None], new - cn[:, None]
    ang = np.arctan2(np.sum(a[0] * b[1] - a[1] * b[0]), np.sum(a * b))
    R = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
    return R, co, cn


def move_particles(mesh: skfem.MeshTri, particles: object,
                   falloff: float | Sequence[float] | None = None) -> skfem.MeshTri:
    """Move particle outline nodes to new outlines, dragging nearby nodes along.

    The particle nodes are placed exactly at the new (subdivided) outline
    vertices. Interior nodes follow each particle's best-fit rigid motion,
    weighted by ``w = (1 - d / falloff)^2`` for a distance ``d`` from the old
    outline (``w = 0`` beyond ``falloff``); wall nodes never move. Connectivity
    is kept, so elements may degrade or invert: check with
    :func:`meshing.remesh_needed`.

    Parameters
    ----------
    mesh
        Mesh with ``particle_nodes`` and ``meshing_recipe`` (from this package).
    particles
        New outlines, the same number and (after subdivision by the mesh's
        ``delta_l``) the same vertex counts as the mesh's particles.
    falloff
        Distance over which interior nodes follow, ``> 0``, one per particle
        or one for all; default twice each particle's circumradius.

    Returns
    -------
    skfem.MeshTri
        Same connectivity, boundaries and subdomains; ``meshing_recipe``
        updated with the new outlines.
    """
    recipe = _recipe(mesh)
    new = _outlines(recipe, particles)
    new = [subdivide(P, recipe.options.get("delta_l")) for P in new]
    p = np.array(mesh.p, dtype=np.float64)
    q = p.copy()
    nodes = mesh.particle_nodes
    fall = np.broadcast_to(np.asarray(np.nan if falloff is None else falloff, dtype=float),
                           (len(new),))
    boundary = np.zeros(p.shape[1], dtype=bool)
    boundary[np.unique(mesh.facets[:, mesh.boundary_facets()])] = True
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
    for idx, P in zip(nodes, new, strict=True):
        q[:, idx] = P
    moved = skfem.MeshTri(q, np.asarray(mesh.t), _boundaries=mesh._boundaries,
                          _subdomains=mesh._subdomains, sort_t=False)
    moved.particle_nodes = nodes
    moved.meshing_recipe = replace(recipe, particles=tuple(new))
    return moved
