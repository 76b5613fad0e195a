"""Meshes for the rounding measures: :func:`renumbered` (random node and element order)
and :func:`mirror_symmetric` (does a reflection map the mesh onto itself)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import skfem

from meshing import BodyFittedMesh


def renumbered(mesh, seed: int):
    """The same mesh with nodes and elements randomly renumbered (same named boundaries).

    Parameters
    ----------
    mesh : skfem.MeshTri or meshing.BodyFittedMesh
    seed : int
        Seed of the random permutations.

    Returns
    -------
    skfem.MeshTri or meshing.BodyFittedMesh
        The type given: a ``BodyFittedMesh`` keeps its recipe, and its
        ``particle_nodes`` are mapped to the new vertex numbers.
    """
    if isinstance(mesh, BodyFittedMesh):
        m, new = _renumbered(mesh.mesh, seed)
        return replace(mesh, mesh=m, particle_nodes=tuple(new[a] for a in mesh.particle_nodes))
    return _renumbered(mesh, seed)[0]


def _renumbered(mesh, seed):
    """``(renumbered MeshTri, new)``: old vertex ``i`` is vertex ``new[i]`` of the new mesh."""
    rng = np.random.default_rng(seed)
    n = mesh.p.shape[1]
    perm = rng.permutation(n)  # new node j is old node perm[j]
    new = np.empty(n, dtype=np.int64)
    new[perm] = np.arange(n)
    t = new[mesh.t][:, rng.permutation(mesh.t.shape[1])]
    t = np.roll(t, int(rng.integers(3)), axis=0)  # a cyclic shift keeps the orientation
    m = skfem.MeshTri(np.ascontiguousarray(mesh.p[:, perm]), np.ascontiguousarray(t), sort_t=False)
    f = np.sort(m.facets, axis=0).astype(np.int64)
    fkey = f[0] * n + f[1]
    order = np.argsort(fkey)
    bnd = {}
    for name, facets in mesh.boundaries.items():
        g = np.sort(new[mesh.facets[:, facets]], axis=0)
        bnd[name] = order[np.searchsorted(fkey, g[0] * n + g[1], sorter=order)]
    return skfem.MeshTri(m.p, m.t, _boundaries=bnd, sort_t=False), new


def mirror_symmetric(mesh, axis: int, value: float, tol: float = 1e-9) -> bool:
    """Whether the mesh maps onto itself under reflection at ``x[axis] = value``."""
    from scipy.spatial import cKDTree

    p = mesh.p
    q = p.copy()
    q[axis] = 2 * value - q[axis]
    scale = float(np.ptp(p, axis=1).max())
    d, idx = cKDTree(p.T).query(q.T)
    if d.max() > tol * scale:
        return False
    mapped = np.sort(idx[mesh.t], axis=0)
    orig = np.sort(mesh.t, axis=0)
    return {tuple(c) for c in mapped.T.tolist()} == {tuple(c) for c in orig.T.tolist()}
