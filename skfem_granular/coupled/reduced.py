"""Rigid particles as unknowns of a coupled system: the prolongation ``u = E z + x_D``.

:class:`ReducedRigid` expresses the velocity DOFs on each free particle's core outline
through the particle's rigid DOFs ``xi = (Vx, Vy, omega)``: ``z = (u_free, xi, p_free)``
and ``E`` maps it to the full fluid vector (``u = V + omega x (x - X)`` at every outline
node), ``x_D`` holding the walls' and the imposed particles' values. The monolithic and
the split couplings both solve for ``z``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .rigid import RigidBodies, RigidParticles


class ReducedRigid(RigidParticles):
    """:class:`RigidParticles` whose free particles' rigid velocities are unknowns.

    Parameters are those of :class:`RigidParticles`.
    """

    def __init__(self, space, fluid, walls: dict, bodies: RigidBodies, *,
                 convection: bool = True, terms=None):
        super().__init__(space, fluid, walls, bodies, convection=convection, terms=terms)
        # the imposed particles' rigid velocities of the step
        self.xi_imposed: np.ndarray | None = None
        # mesh velocity of a moving mesh (None: fixed mesh)
        self.w_mesh: np.ndarray | None = None
        self._build_prolongation()
        self.reference_op = self.op  # the operator on the mesh as built (moved ones derive)

    @property
    def ndof_rigid(self) -> int:
        """Rigid DOFs per particle (3 with rotation, 2 without)."""
        return 3 if self.rotation else 2

    def _build_prolongation(self):
        sp_ = self.space
        nu, N = sp_.nu, sp_.N
        on_particle = np.zeros(N, dtype=bool)
        for d in self.particle_dofs:
            on_particle[d] = True
        fixed = np.zeros(N, dtype=bool)
        fixed[self.op.fixed] = True  # walls, particles and the pinned pressure
        u_free = np.flatnonzero(~fixed[:nu])
        p_free = nu + np.flatnonzero(~fixed[nu:])
        r = self.ndof_rigid
        self.n_ufree = u_free.size
        # "velocity-like" unknowns come first; imposed particles have no rigid unknowns
        self.nu_z = u_free.size + r * self.free_particles.size
        self.nz = self.nu_z + p_free.size
        self.u_free, self.p_free = u_free, p_free
        self.rigid_slice = slice(u_free.size, self.nu_z)
        self._assemble_prolongation()

    def _assemble_prolongation(self):
        """``E`` (and ``E^T``) with the rotation's lever arms at the current node positions."""
        if getattr(self, "_lever_slots", None) is not None:  # moved mesh: new lever values only
            levers = self.all_levers()
            if self.imposed.any():  # the free particles' entries, in particle order
                levers = levers[~self.imposed[self._owner]]
            self.E.data[self._lever_slots[0]] = levers
            self.ET.data[self._lever_slots[1]] = levers
            return
        u_free, p_free = self.u_free, self.p_free
        r = self.ndof_rigid
        rows = [u_free, p_free]
        cols = [np.arange(u_free.size), self.nu_z + np.arange(p_free.size)]
        vals = [np.ones(u_free.size), np.ones(p_free.size)]
        for j, k in enumerate(self.free_particles):
            d, c, lever = self.levers(k)
            base = u_free.size + r * j
            rows += [d]
            cols += [base + c.astype(np.int64)]
            vals += [np.ones(d.size)]
            if self.rotation:
                rows += [d]
                cols += [np.full(d.size, base + 2)]
                vals += [lever]
        self.E = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                               shape=(self.space.N, self.nz))
        self.ET = self.E.T.tocsr()
        if self.rotation:  # where the lever values sit in E and E^T, for moved meshes
            marks = [np.zeros(u_free.size), np.zeros(p_free.size)]
            n_lever = 0
            for k in self.free_particles:
                d = self.particle_dofs[k]
                marks += [np.zeros(d.size), n_lever + 1 + np.arange(d.size, dtype=float)]
                n_lever += d.size
            tagged = sp.csr_matrix((np.concatenate(marks), (np.concatenate(rows),
                                                            np.concatenate(cols))),
                                   shape=self.E.shape)
            tagged.data[tagged.data == 0] = 0.0
            tagged_T = tagged.T.tocsr()

            def slots(M):
                assert np.array_equal(M.indptr, (self.E if M is tagged else self.ET).indptr)
                pos = np.flatnonzero(M.data > 0)
                return pos[np.argsort(M.data[pos])]

            self._lever_slots = (slots(tagged), slots(tagged_T))

    def move(self, space, centers: np.ndarray, w_mesh: np.ndarray | None) -> None:
        """Evaluate the coupled system on a moved mesh (ALE) from now on.

        Parameters
        ----------
        space : TaylorHood
            ``reference_space.moved(p)``: the mesh with the particles where they are.
        centers : (2, K) ndarray
            The particles' centres there (the rotations' lever arms are taken about them).
        w_mesh : ndarray or None
            Mesh velocity (velocity DOFs) of the step being solved (None: at rest).
        """
        self.space = space
        self.op = self.reference_op.moved(space)
        self.centers = np.array(centers, dtype=float).reshape(2, self.K)
        self.w_mesh = w_mesh
        self._assemble_prolongation()

    def rigid(self, z: np.ndarray) -> np.ndarray:
        """Rigid DOFs ``(3, K)`` (``Vx, Vy, omega``) of an unknown vector ``z`` (the
        imposed particles' columns: the step's ``xi_imposed``)."""
        free = self.free_particles
        xi = z[self.rigid_slice].reshape(free.size, self.ndof_rigid).T
        out = np.zeros((3, self.K))
        out[: self.ndof_rigid, free] = xi
        if self.xi_imposed is not None:
            out[:, self.imposed] = self.xi_imposed[:, self.imposed]
        return out

    def _rigid_vector(self, xi3: np.ndarray) -> np.ndarray:
        """The rigid unknowns (free particles') of ``(3, K)`` values, as ``z`` orders them."""
        return np.asarray(xi3, dtype=float)[: self.ndof_rigid][:, self.free_particles].T.ravel()

    def x_dirichlet(self, t: float | None = None) -> np.ndarray:
        """Full fluid vector holding the wall values only."""
        x = np.zeros(self.space.N)
        if self.wall_dirichlet is not None:
            d = self.wall_dirichlet.dofs
            x[d] = self.wall_dirichlet.values(t)[d]
        return x

    def to_z(self, x: np.ndarray, xi3: np.ndarray) -> np.ndarray:
        """Unknown vector from a full fluid vector and rigid DOFs."""
        z = self.ET @ x  # free DOFs map one to one; rigid rows are overwritten
        z[self.rigid_slice] = self._rigid_vector(xi3)
        return z

    # ------------------------------------------------------------------ algebra
    def inertia_diag(self) -> np.ndarray:
        m = np.stack([self.mass, self.mass, self.inertia])[: self.ndof_rigid]
        return m[:, self.free_particles].T.ravel()

    def impose(self, xi_imposed, xi_n, xi_guess):
        """Record the imposed particles' velocities at the step's end (Dirichlet data on their
        outlines) and put them into the first guess, which is returned."""
        self.xi_imposed = None
        if not self.imposed.any():
            return xi_guess
        if xi_imposed is None:
            raise ValueError(f"{type(self).__name__}.step: xi_imposed (3, K) is required: "
                             "the coupling has particles with a prescribed motion")
        self.xi_imposed = np.array(xi_imposed, dtype=float).reshape(3, self.K)
        # the imposed particles where their motion puts them, from the first mesh on
        xi_guess = np.array(xi_n if xi_guess is None else xi_guess, dtype=float)
        xi_guess[:, self.imposed] = self.xi_imposed[:, self.imposed]
        return xi_guess

    def rigid_rhs(self, hist_xi, F_ext, T_ext) -> np.ndarray:
        """The rigid rows' right-hand side: external forces minus the BDF2 history's
        inertia ``m (a1 xi_n + a2 xi_prev)``."""
        m3 = np.stack([self.mass, self.mass, self.inertia])
        ext = np.vstack([F_ext, T_ext[None, :]])
        return self._rigid_vector(ext - m3 * hist_xi)

    def first_iterate(self, u, p, xi) -> np.ndarray:
        """The corrector's first iterate from velocity, pressure (or zeros) and rigid guesses."""
        x0 = np.zeros(self.space.N)
        x0[: self.space.nu] = u
        if p is not None:
            x0[self.space.nu:] = p
        return self.to_z(x0, xi)
