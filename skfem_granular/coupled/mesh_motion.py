"""Moving the mesh with the particles (ALE): outline nodes rigid, the rest a smooth extension.

Each particle's outline vertices move rigidly with the particle, from the pose
the mesh was built for to the pose now; wall vertices stay, or slide along
straight axis-parallel walls (:func:`sliding_wall_nodes`); every other vertex
follows the harmonic extension of those boundary displacements, a Laplace
problem for the displacement ``d`` with the element-size stiffening of ALE
codes: the diffusion coefficient of a triangle is ``1 / area``, so small
elements near the particles move almost rigidly and the large ones far away
take up the deformation. The stiffness matrix is factorised once per mesh (and
component, when walls slide); each motion is then one triangular solve per
component. Optionally (:data:`RELAX_ANGLE`, off by default) the interior vertices
near triangles below a given angle then move part of the way towards their
neighbours' mean.

:func:`mesh_quality` measures what a motion did to the triangles (smallest
angle, smallest signed-area ratio to the built mesh), for the remeshing rule of
:class:`~skfem_granular.coupled.mesh_keeper.MeshKeeper`.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .._jit import lazy_njit

#: Relaxation of poor triangles (degrees; 0: off, the default). With ``RELAX_ANGLE > 0``
#: every interior vertex within two rings of a triangle whose smallest angle is below it
#: moves towards the mean of its neighbours, by the fraction the triangle falls short
#: (``(RELAX_ANGLE - angle) / RELAX_ANGLE``, the largest over the triangles near it): a
#: continuous function of the poses, so the mesh velocity stays the derivative of the
#: vertex positions (:meth:`MeshMotion.positions`).
RELAX_ANGLE = 0.0


class MeshMotion:
    """Vertex positions of a mesh for the particles' current poses.

    Parameters
    ----------
    mesh : skfem.MeshTri
        The mesh as built (the reference configuration).
    particle_nodes : sequence of ndarray
        Vertex indices of each particle's outline.
    poses_ref : (3, K) ndarray
        ``(x, y, angle)`` of each particle when the mesh was built.
    slide_walls : bool
        Let the vertices of straight axis-parallel walls slide along them
        (:func:`sliding_wall_nodes`); otherwise every wall vertex stays put.
    """

    def __init__(self, mesh, particle_nodes, poses_ref, slide_walls: bool = True):
        self.p_ref = np.asarray(mesh.p, dtype=float)
        self.t = mesh.t
        self._mesh = mesh  # its edges (``mesh.facets``) when the relaxation needs them
        self.poses_ref = np.array(poses_ref, dtype=float).reshape(3, -1)
        self.particle_nodes = [np.asarray(n, dtype=np.int64) for n in particle_nodes]
        # all outline vertices at once: which particle each belongs to, and its arm there
        self._outline = np.concatenate(self.particle_nodes or [np.zeros(0, dtype=np.int64)])
        self._owner = np.repeat(np.arange(len(self.particle_nodes)),
                                [n.size for n in self.particle_nodes])
        self._arm = self.p_ref[:, self._outline] - self.poses_ref[:2, self._owner]
        nv = self.p_ref.shape[1]
        boundary = np.zeros(nv, dtype=bool)
        boundary[mesh.boundary_nodes()] = True
        for n in self.particle_nodes:
            boundary[n] = True
        slide = (sliding_wall_nodes(mesh, self.particle_nodes) if slide_walls
                 else (np.zeros(0, dtype=np.int64),) * 2)
        #: per component: the vertices whose displacement is solved for (interior ones and
        #: wall ones sliding along that axis) and the ones it is imposed on
        self.free, self.fixed = [], []
        A = self._stiffness()
        for c in range(2):
            free = ~boundary
            free[slide[c]] = True
            self.free.append(np.flatnonzero(free))
            self.fixed.append(np.flatnonzero(~free))
        self.sliding = slide
        self._shared = all(s_.size == 0 for s_ in slide)
        if self._shared:  # both components share one factorisation
            f, b = self.free[0], self.fixed[0]
        else:  # both components in one block-diagonal system: one solve per motion
            A = sp.block_diag([A, A], format="csr")
            f = np.concatenate([self.free[0], nv + self.free[1]])
            b = np.concatenate([self.fixed[0], nv + self.fixed[1]])
        self._blocks = (f, b, A[f][:, b], spla.splu(sp.csc_matrix(A[f][:, f])) if f.size else None)
        from meshing.quality import signed_areas  # meshing: imported when a mesh moves

        self.area_ref = signed_areas(self.p_ref, self.t)

    def _stiffness(self) -> sp.csr_matrix:
        """P1 Laplacian with coefficient ``1 / area`` per triangle (element-size stiffening)."""
        p, t = self.p_ref, self.t
        e = [p[:, t[2]] - p[:, t[1]], p[:, t[0]] - p[:, t[2]], p[:, t[1]] - p[:, t[0]]]
        area = np.abs(0.5 * (e[2][0] * (-e[1][1]) - e[2][1] * (-e[1][0])))
        rows, cols, vals = [], [], []
        for i in range(3):
            for j in range(3):
                # int grad phi_i . grad phi_j = e_i . e_j / (4 area); times 1 / area
                rows.append(t[i])
                cols.append(t[j])
                vals.append((e[i] * e[j]).sum(axis=0) / (4.0 * area * area))
        nv = p.shape[1]
        return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows),
                                                     np.concatenate(cols))), shape=(nv, nv))

    def positions(self, poses: np.ndarray) -> np.ndarray:
        """Vertex positions ``(2, nv)`` with every particle at ``poses`` ``(3, K)`` (the
        harmonic extension, relaxed near poor triangles when :data:`RELAX_ANGLE` > 0)."""
        poses = np.asarray(poses, dtype=float)
        d = np.zeros_like(self.p_ref)
        n, k, r = self._outline, self._owner, self._arm  # every outline moved rigidly
        turn = poses[2, k] - self.poses_ref[2, k]
        c, s = np.cos(turn), np.sin(turn)
        d[0, n] = poses[0, k] + (c * r[0] - s * r[1]) - self.p_ref[0, n]
        d[1, n] = poses[1, k] + (s * r[0] + c * r[1]) - self.p_ref[1, n]
        f, b, A_fb, lu = self._blocks
        if lu is None:
            return self.p_ref + d
        if self._shared:  # no sliding wall: both components at once, one factorisation
            rhs = -(A_fb @ d[:, b].T)
            d[:, f] = lu.solve(np.ascontiguousarray(rhs)).T
        else:
            flat = d.ravel()  # x displacements, then y (a view: d is C-contiguous)
            flat[f] = lu.solve(-(A_fb @ flat[b]))
        p = self.p_ref + d
        return p if RELAX_ANGLE <= 0.0 else self._relaxed(p, RELAX_ANGLE)

    def _relaxed(self, p: np.ndarray, angle: float) -> np.ndarray:
        """``p`` with the interior vertices near triangles below ``angle`` degrees moved
        towards their neighbours' mean (:data:`RELAX_ANGLE`)."""
        from meshing.quality import angles  # meshing: imported when a mesh moves

        t = self.t
        short = np.clip((angle - angles(p, t).min(axis=0)) / angle, 0.0, 1.0)
        if not short.any():
            return p
        nv = p.shape[1]
        w = np.zeros(nv)
        for k in range(3):  # the vertices of a poor triangle
            np.maximum.at(w, t[k], short)
        if not hasattr(self, "_edges"):
            edges = self._mesh.facets  # every edge once
            A = sp.csr_matrix((np.ones(2 * edges.shape[1]),
                               (np.r_[edges[0], edges[1]], np.r_[edges[1], edges[0]])),
                              shape=(nv, nv))
            interior = np.zeros((2, nv), dtype=bool)
            interior[0, self.free[0]] = interior[1, self.free[1]] = True
            self._edges = (edges, A, np.asarray(A.sum(axis=1)).ravel(),
                           interior[0] & interior[1])
        edges, A, degree, interior = self._edges
        ring = w.copy()  # and their neighbours
        np.maximum.at(ring, edges[0], w[edges[1]])
        np.maximum.at(ring, edges[1], w[edges[0]])
        ring[~interior] = 0.0  # outlines and walls stay where the motion puts them
        mean = (A @ p.T).T / degree
        return p + ring * (mean - p)


def sliding_wall_nodes(mesh, particle_nodes) -> tuple[np.ndarray, np.ndarray]:
    """Wall vertices that may slide along their wall: ``(along x, along y)``.

    A vertex of the outer boundary slides along ``x`` when every boundary edge at it is
    horizontal (it sits inside a horizontal wall), along ``y`` when every one is
    vertical; corners, vertices of slanted walls and particle outlines stay put.
    Sliding keeps the wall where it is (the vertex moves along the wall's line) and lets
    the triangles between a wall and a particle moving along it shear less.
    """
    p = mesh.p
    facets = mesh.facets[:, mesh.boundary_facets()]
    on_particle = np.zeros(p.shape[1], dtype=bool)
    for n in particle_nodes:
        on_particle[n] = True
    facets = facets[:, ~(on_particle[facets[0]] | on_particle[facets[1]])]
    d = np.abs(p[:, facets[1]] - p[:, facets[0]])
    scale = 1e-12 * float(np.abs(p).max())
    kinds = [d[1] <= scale, d[0] <= scale]  # horizontal, vertical edges
    count = np.bincount(facets.ravel(), minlength=p.shape[1])
    out = []
    for along in kinds:
        same = np.bincount(facets[:, along].ravel(), minlength=p.shape[1])
        out.append(np.flatnonzero((count > 0) & (same == count)).astype(np.int64))
    return out[0], out[1]


def mesh_quality(p: np.ndarray, t: np.ndarray, area_ref: np.ndarray) -> tuple[float, float]:
    """Smallest angle (degrees) of the triangles at ``p``, and the smallest ratio of a
    triangle's signed area to its area in the built mesh (<= 0: inverted)."""
    angle, ratio = _quality(np.ascontiguousarray(p, dtype=float), t, area_ref)
    return float(np.degrees(angle)), float(ratio)


@lazy_njit  # numba.njit(cache=True) at the first call
def _quality(p, t, area_ref):  # pragma: no cover (compiled)
    """Smallest angle (radians) and smallest signed-area ratio, in one pass."""
    smallest, ratio = np.pi, np.inf
    for e in range(t.shape[1]):
        a, b, c = t[0, e], t[1, e], t[2, e]
        ex = (p[0, c] - p[0, b], p[0, a] - p[0, c], p[0, b] - p[0, a])  # edge i opposite i
        ey = (p[1, c] - p[1, b], p[1, a] - p[1, c], p[1, b] - p[1, a])
        area = 0.5 * ((p[0, b] - p[0, a]) * (p[1, c] - p[1, a])
                      - (p[1, b] - p[1, a]) * (p[0, c] - p[0, a]))
        ratio = min(ratio, area / area_ref[e])
        for i in range(3):  # the angle at vertex i, between the edges that meet there
            j, k = (i + 1) % 3, (i + 2) % 3
            ux, uy, vx, vy = -ex[j], -ey[j], ex[k], ey[k]
            smallest = min(smallest, np.arctan2(abs(ux * vy - uy * vx), ux * vx + uy * vy))
    return smallest, ratio
