"""Repairing the moving mesh in place: a few edges flipped instead of a new mesh.

On a moving mesh (ALE) a remesh is asked for when one triangle, of hundreds of thousands,
falls below the angle or area bound now or one step ahead
(:func:`~.ale_rules.remesh_reason`); the mesh around it is still good. :func:`flip_plan`
flips edges (:func:`meshing.flips.flip_repair`) judged over where the vertices were at
``t_{n-1}``, where they are and where the particles' extrapolated poses take them
:data:`REPAIR_AHEAD` steps ahead, the first three first (a flip may not spoil what the
remesh rule judges to help a configuration further ahead). The vertices stay, so the
pressure and every velocity DOF on a kept vertex or edge keep their values; only the
midpoint DOFs of the new edges are interpolated (:func:`flip_transfer`), each history in
its own configuration.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from scipy.sparse import csgraph

from ..fluid.points import evaluation_matrix

#: Reasons of :func:`~.ale_rules.remesh_reason` a repair may answer (a particle that has
#: travelled far from where its mesh was graded needs a new grading: a new mesh).
REPAIRABLE = ("angle", "area", "ahead")

#: Flip edges of triangles below this smallest angle (degrees), over the configurations
#: (chosen by measurement, as :data:`REPAIR_AHEAD`: docs/benchmarks.md, "Repairing the
#: moving mesh").
REPAIR_ANGLE = 20.0

#: The configurations judged: the poses extrapolated 1, 2, ... this many steps ahead.
REPAIR_AHEAD = 5

#: The interpolated velocities are made divergence-free on the flipped triangles and
#: this many rings of triangles around them (:func:`divergence_free_nearby`).
PROJECTION_RINGS = 2


def flip_plan(t, nodes_prev, nodes_n, ahead):
    """The flipped triangles of the mesh ``t`` at ``nodes_n`` ``(2, nv)``: ``(t_new,
    changed columns)`` by :func:`meshing.flips.flip_repair` over ``nodes_prev`` (None: not
    judged), ``nodes_n`` and the positions in ``ahead`` (a list of ``(2, nv)``)."""
    from meshing.flips import flip_repair  # meshing: imported when a mesh is repaired

    configs = [nodes_n, *([] if nodes_prev is None else [nodes_prev]), *ahead]
    # what the remesh rule judges (now and one step ahead) comes first
    near = len(configs) - max(len(ahead) - 1, 0)
    t_new, changed = flip_repair(t, configs, REPAIR_ANGLE, near=near)
    return t_new.astype(t.dtype), changed


def flip_transfer(old_space, new_space, p: np.ndarray, changed: np.ndarray) -> sp.csr_matrix:
    """``(N_new, N_old)`` map of scalar P2 DOFs from ``old_space`` onto ``new_space``, the
    same vertices with the triangles ``changed`` flipped, in the configuration ``p``
    ``(2, nv)``: vertex and kept-edge DOFs copied, each new edge's midpoint DOF the old
    field there (located in the old triangles ``changed``)."""
    old_mesh, new_mesh = old_space.mesh, new_space.mesh
    nv = p.shape[1]
    old_keys = _edge_keys(old_mesh.facets, nv)
    new_keys = _edge_keys(new_mesh.facets, nv)
    order = np.argsort(old_keys)
    at = np.searchsorted(old_keys, new_keys, sorter=order).clip(max=order.size - 1)
    match = order[at]
    kept = old_keys[match] == new_keys
    n_old, n_new = nv + old_keys.size, nv + new_keys.size
    rows = [np.arange(nv), nv + np.flatnonzero(kept)]
    cols = [np.arange(nv), nv + match[kept]]
    vals = [np.ones(nv), np.ones(int(kept.sum()))]
    E = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(n_new, n_old))
    fresh = np.flatnonzero(~kept)
    if fresh.size:
        ends = new_mesh.facets[:, fresh]
        mid = 0.5 * (p[:, ends[0]] + p[:, ends[1]])
        cells, X = _locate(p, old_mesh.t[:, changed], mid)
        E_new = evaluation_matrix(old_space.numbering("scalar"), changed[cells], X)
        E = E + sp.csr_matrix(sp.coo_matrix(
            (np.ones(fresh.size), (nv + fresh, np.arange(fresh.size))),
            shape=(n_new, fresh.size))) @ E_new
    return sp.csr_matrix(E)


def _edge_keys(facets: np.ndarray, nv: int) -> np.ndarray:
    lo, hi = np.sort(facets, axis=0)
    return lo.astype(np.int64) * nv + hi


def _locate(p, tri, points):
    """For each point ``(2, n)``: the triangle of ``tri`` ``(3, m)`` that holds it (the
    largest smallest barycentric coordinate) and its reference coordinates ``(2, n)``."""
    a, b, c = p[:, tri[0]], p[:, tri[1]], p[:, tri[2]]  # (2, m)
    J = np.stack([b - a, c - a], axis=1)  # (2, 2, m): columns the edges from a
    det = J[0, 0] * J[1, 1] - J[0, 1] * J[1, 0]
    d = points[:, :, None] - a[:, None, :]  # (2, n, m)
    xi = (J[1, 1] * d[0] - J[0, 1] * d[1]) / det
    eta = (-J[1, 0] * d[0] + J[0, 0] * d[1]) / det
    inside = np.minimum(np.minimum(xi, eta), 1.0 - xi - eta)
    best = inside.argmax(axis=1)
    n = np.arange(points.shape[1])
    if np.any(inside[n, best] < -1e-9):
        raise ValueError("flip_transfer: a new edge's midpoint lies outside the flipped "
                         "triangles")
    return best, np.vstack([xi[n, best], eta[n, best]])


def divergence_free_nearby(space, free: np.ndarray, u: np.ndarray,
                           cells: np.ndarray) -> np.ndarray:
    """``u`` with its divergence on the triangles ``cells`` and :data:`PROJECTION_RINGS`
    rings around them removed: the ``diag(M)``-nearest velocity whose divergence vanishes
    there (:func:`~skfem_granular.fluid.projection.divergence_free_projection` on that
    patch), changing only DOFs inside it (not on its rim, not ``free``'s Dirichlet ones).

    Parameters
    ----------
    space : TaylorHood
        The mesh (in the configuration ``u`` belongs to).
    free : ndarray
        The operator's free DOFs (velocities below ``space.nu``, then pressures).
    u : (nu,) ndarray
    cells : ndarray
        The triangles whose divergence changed (the flipped ones).
    """
    t = space.mesh.t
    patch = np.zeros(t.shape[1], dtype=bool)
    patch[cells] = True
    for _ in range(PROJECTION_RINGS):  # the triangles that share a vertex with the patch
        near = np.zeros(space.mesh.p.shape[1], dtype=bool)
        near[t[:, patch]] = True
        patch |= near[t].any(axis=0)
    vdofs = space.velocity_dofs.element_dofs
    inside = np.zeros(space.nu, dtype=bool)
    inside[vdofs[:, patch]] = True
    inside[vdofs[:, ~patch]] = False  # the rim touches triangles outside
    mask = np.zeros(space.nu, dtype=bool)
    mask[free[free < space.nu]] = True
    J = np.flatnonzero(inside & mask)
    rows = np.zeros(space.N - space.nu, dtype=bool)
    rows[space.pressure_dofs.element_dofs[:, patch]] = True
    pfree = np.zeros_like(rows)
    pfree[free[free >= space.nu] - space.nu] = True
    R = np.flatnonzero(rows & pfree)
    B, M = space.blocks(("B", "M"))
    BR = sp.csr_matrix(B)[R]
    BRJ = sp.csr_matrix(BR[:, J])
    D = M.diagonal()[J]
    S = sp.csr_matrix(BRJ @ sp.diags(1.0 / D) @ BRJ.T)
    r = BR @ u
    q = np.zeros(R.size)
    # one dense least-squares solve per connected piece of the patch (each holds the
    # constant pressure: its total flux is what its rim leaves it)
    n_pieces, piece = csgraph.connected_components(S, directed=False)
    for k in range(n_pieces):
        rows_k = np.flatnonzero(piece == k)
        S_k = S[rows_k][:, rows_k].toarray()
        q[rows_k] = sla.lstsq(S_k, r[rows_k], lapack_driver="gelsy")[0]
    v = np.array(u, dtype=float)
    v[J] -= (BRJ.T @ q) / D
    return v


def transfer_by_flips(state, old_space, new_space, changed, free=None) -> dict:
    """The fluid histories of ``state`` on ``new_space`` (the flipped mesh), as a dict for
    ``dataclasses.replace``: velocities (and their derivatives) by :func:`flip_transfer`,
    ``u_n`` at ``state.nodes_n``, ``u_prev`` at ``state.nodes_prev``, both made
    divergence-free around the flipped triangles (:func:`divergence_free_nearby`, with
    the operator's free DOFs ``free``; None: not); pressures kept."""
    s = state
    E_n = flip_transfer(old_space, new_space, s.nodes_n, changed)
    E_prev = (E_n if s.nodes_prev is None
              else flip_transfer(old_space, new_space, s.nodes_prev, changed))

    def moved(E, u):
        if u is None:
            return None
        out = np.empty(2 * E.shape[0])
        out[0::2], out[1::2] = E @ u[0::2], E @ u[1::2]
        return out

    u_n, u_prev = moved(E_n, s.u_n), moved(E_prev, s.u_prev)
    if free is not None:
        u_n = divergence_free_nearby(new_space, free, u_n, changed)
        if u_prev is not None:
            prev = new_space if s.nodes_prev is None else new_space.moved(s.nodes_prev)
            u_prev = divergence_free_nearby(prev, free, u_prev, changed)
    fields = {"u_n": u_n, "du_n": moved(E_n, s.du_n), "u_prev": u_prev,
              "du_prev": moved(E_prev, s.du_prev)}
    return fields
