"""The discrete Navier-Stokes operator on one mesh for one set of boundary data.

``R(x) = [ (c rho M + eta K) u + rho N(u) u + B^T p - f ;  B u ]`` with
``x = [u, p]``; ``c = 0`` for steady problems and ``c = a0`` inside a BDF2
step (the history goes into ``f``). Dirichlet velocity DOFs (and, in closed
domains, one pinned pressure DOF) are eliminated: solvers act on the free
DOFs only while the fixed ones hold their prescribed values in ``x``.
"""

from __future__ import annotations

import copy
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from .boundary import DirichletData
from .geometry import with_data
from .properties import Fluid
from .space import TaylorHood
from .user_terms import UserBlocks, UserTerms

#: indices and indptr of a velocity block, the convection pattern's indices, and the
#: positions of the block's entries in that pattern (None: not within it)
_Positions = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]


class NavierStokesOperator:
    """Residual, Jacobian and reduced systems of the P2/P1 Navier-Stokes equations.

    Parameters
    ----------
    space : TaylorHood
        The discretisation.
    fluid : Fluid
        Density and viscosity.
    dirichlet : DirichletData
        Velocity boundary data.
    convection : bool
        Include ``rho N(u) u`` (Navier-Stokes) or not (Stokes).
    viscous : {"auto", "symmetric", "laplace"}
        Form of the viscous term. ``"auto"``: symmetric gradient in closed
        domains, Laplacian ("do-nothing" outflow) when a boundary is open.
    body_force : None, (2,) array_like or callable
        Force density ``f`` in N/m^3 (constant or ``f(x, y) -> (fx, fy)``).
        The hydrostatic part of gravity is *not* included: pressures are
        dynamic pressures.
    terms : UserTerms, optional
        scikit-fem forms added to the momentum and continuity equations
        (:class:`~skfem_granular.fluid.user_terms.UserTerms`), assembled on the current
        mesh at the current velocity and at :attr:`time`.

    Notes
    -----
    Pressure in a closed domain is defined up to a constant: the first
    pressure DOF is pinned to zero during the solve and the result is then
    shifted to zero mean over the domain (:meth:`normalize_pressure`).
    """

    def __init__(self, space: TaylorHood, fluid: Fluid, dirichlet: DirichletData,
                 convection: bool = False, viscous: str = "auto", body_force=None,
                 terms=None):
        if not isinstance(fluid, Fluid):
            raise ValueError("fluid: a skfem_granular.Fluid is required, "
                             f"got {type(fluid).__name__}")
        self.space = space
        self.fluid = fluid
        self.dirichlet = dirichlet
        self.convection = bool(convection)
        if viscous == "auto":
            viscous = "symmetric" if dirichlet.closed else "laplace"
        self.viscous = viscous
        self._K_unit = space.K(viscous)  # the space's, unit viscosity (scaled when used)
        self._body_force_spec = body_force
        self.f = self._body_force(body_force)
        if terms is not None and not isinstance(terms, UserTerms):
            raise ValueError("terms: a skfem_granular.fluid.UserTerms is required, "
                             f"got {type(terms).__name__}")
        self.terms = terms
        #: the time at which the user terms are assembled (the end of a time step)
        self.time = 0.0
        # (time, velocity, UserBlocks) of the last assembly
        self._user: tuple[float, np.ndarray, UserBlocks] | None = None
        nu = space.nu
        fixed = dirichlet.dofs
        self.pinned = dirichlet.closed
        if self.pinned:
            fixed = np.concatenate([fixed, [nu]])
        self.fixed = np.asarray(fixed, dtype=np.int64)
        mask = np.ones(space.N, dtype=bool)
        mask[self.fixed] = False
        self.free = np.flatnonzero(mask)
        self.nu_free = int(np.count_nonzero(self.free < nu))
        self._zero_p = sp.csr_matrix((space.np_, space.np_))
        # c_mass -> c rho M + eta K (the last two kept)
        self._velocity_blocks: dict[float, sp.csr_matrix] = {}
        # [(indices, indptr of A_uu, the convection pattern's indices, positions of A_uu's
        # entries in that pattern)]: one list shared by the operator and its moved copies,
        # whose blocks and kernels keep the reference patterns
        self._conv_positions: list[_Positions | None] = [None]

    def moved(self, space) -> NavierStokesOperator:
        """The same operator on a moved discretisation (``space = self.space.moved(p)``).

        Boundary data, free DOFs and patterns are kept; the blocks, the convection
        kernel and the boundary values follow the moved mesh. A body force is
        integrated anew on the moved mesh.
        """
        new = copy.copy(self)
        new.space = space
        # on the reference patterns: the transpose as a gather, the scaled K on M's pattern
        new._Bt = space.reference_blocks.pu.transposed_csr(space.B.data)
        new.__dict__.pop("_B_lower", None)  # built when a matrix is (from B's arrays)
        new.dirichlet = self.dirichlet.moved(space)
        new._K_unit = space.K(self.viscous)
        new._velocity_blocks = {}
        new._user = None
        for cached in ("_reduced_pattern", "_pressure_weights", "_free_pressure_mass",
                       "_free_pressure_laplace"):
            new.__dict__.pop(cached, None)  # geometric caches: the moved mesh's own
        if self._body_force_spec is not None:
            new.f = new._body_force(self._body_force_spec)
        return new

    def _body_force(self, body_force) -> np.ndarray:
        from skfem import asm

        from .boundary import evaluate
        from .forms import body_force as form

        sp_ = self.space
        if body_force is None:
            return np.zeros(sp_.nu)
        if callable(body_force):
            x = sp_.ub.global_coordinates().value
            fx, fy = body_force(x[0], x[1])
            val = np.array([np.broadcast_to(fx, x[0].shape), np.broadcast_to(fy, x[0].shape)],
                           dtype=float)
        else:
            c = evaluate(body_force, np.zeros(1), np.zeros(1), None, "body_force")[:, 0]
            val = np.broadcast_to(c[:, None, None], (2,) + sp_.ub.dx.shape)
        if not np.all(np.isfinite(val)):
            raise ValueError("body_force: contains NaN or inf")
        return asm(form, sp_.ub, f=val)

    # blocks -----------------------------------------------------------------
    @cached_property
    def _Bt(self) -> sp.csr_matrix:
        """``B^T`` in CSR format (sorted indices), built once."""
        return sp.csr_matrix(self.space.B.T)

    @cached_property
    def _B_lower(self) -> sp.csr_matrix:
        """The lower block row ``[B, 0]`` of the saddle-point matrix."""
        B = self.space.B
        if self.space.reference is not self.space:  # a moved mesh: B's arrays, wider
            return sp.csr_matrix((B.data, B.indices, B.indptr),
                                 shape=(B.shape[0], B.shape[0] + B.shape[1]))
        return sp.hstack([sp.csr_matrix(B), self._zero_p], format="csr")

    @property
    def K(self) -> sp.csr_matrix:
        """The viscous block ``eta K``, on the space's pattern (its index arrays).

        Built on each access and not kept (15 MB at 95k DOFs during a steady solve's
        factorisations): the space keeps the unit-viscosity block, this scales it.
        """
        return with_data(self._K_unit, self.fluid.viscosity * self._K_unit.data)

    def velocity_block(self, c_mass: float = 0.0) -> sp.csr_matrix:
        """Linear velocity block ``c rho M + eta K`` (do not modify).

        Cached per ``c_mass > 0`` (the last two); ``eta K`` alone (``c_mass = 0``) is
        :attr:`K`, built on each call."""
        if c_mass == 0.0:
            return self.K
        A = self._velocity_blocks.get(c_mass)
        if A is None:
            M = self.space.M
            K = self.K
            if self.space.reference is not self.space:  # a moved mesh: M, K share a pattern
                A = with_data(M, (c_mass * self.fluid.density) * M.data + K.data)
            else:
                A = (c_mass * self.fluid.density) * M + K
            if len(self._velocity_blocks) >= 2:
                self._velocity_blocks.pop(next(iter(self._velocity_blocks)))
            self._velocity_blocks[c_mass] = A
        return A

    def matrix(self, A_uu: sp.spmatrix, C: sp.spmatrix | None = None) -> sp.csr_matrix:
        """Full saddle-point matrix ``[[A, B^T], [B, 0]]`` (``[B + C, 0]`` below with a
        user continuity block ``C``)."""
        A = sp.csr_matrix(A_uu)
        if not A.has_canonical_format:
            A = A.copy()
            A.sum_duplicates()
        lower = self._B_lower
        if C is not None:
            lower = sp.hstack([sp.csr_matrix(self.space.B) + C, self._zero_p], format="csr")
        N = A.shape[0] + lower.shape[0]
        if N >= 2**31 - 1 or A.nnz + self._Bt.nnz + lower.nnz >= 2**31 - 1:
            top = sp.hstack([A, self._Bt], format="csr")
            return sp.vstack([top, lower], format="csr")
        from .pattern_numba import stack_saddle

        # the rows of A and B^T side by side, then [B, 0]: every stored entry in sorted
        # order, the arrays scipy's hstack and vstack of the CSR blocks give (those are
        # 3-4 s at 1000 grains, this is one pass)
        data, indices, indptr = stack_saddle(A.data, A.indices, A.indptr, self._Bt.data,
                                             self._Bt.indices, self._Bt.indptr, A.shape[1],
                                             lower.data, lower.indices, lower.indptr)
        return sp.csr_matrix((data, indices, indptr.astype(np.int32)), shape=(N, N))

    def linear_matrix(self, A_uu: sp.spmatrix, x: np.ndarray | None = None) -> sp.csr_matrix:
        """:meth:`matrix` of ``A_uu`` with the user terms' matrices (at ``x``, default
        where they were last assembled): the matrix of the linear part of the system."""
        ub = self.user_blocks(x)
        if ub is None:
            return self.matrix(A_uu)
        return self.matrix(A_uu if ub.A is None else A_uu + ub.A, ub.C)

    # user terms -------------------------------------------------------------
    @property
    def linear(self) -> bool:
        """Whether one solve with :meth:`linear_matrix` is exact: no convection and no
        user terms (whose coefficients may change with the velocity and the time)."""
        return not self.convection and self.terms is None

    def user_blocks(self, x: np.ndarray | None = None) -> UserBlocks | None:
        """The user terms assembled on this mesh at :attr:`time` and the velocity of ``x``
        (default: the velocity of the last assembly, or rest); ``None`` without terms.

        The last assembly is kept: the residual and the Jacobian at one iterate share it.
        """
        if self.terms is None:
            return None
        held = self._user
        if x is None:
            u = held[1] if held is not None else np.zeros(self.space.nu)
        else:
            u = x[: self.space.nu]
        if held is None or held[0] != self.time or not np.array_equal(held[1], u):
            held = self._user = (self.time, np.array(u, dtype=float),
                                 self.terms.assemble(self.space, u, self.time))
        return held[2]

    def reduced_bdf2_system(self, a0: float) -> tuple:
        """The linear BDF2-Stokes system for ``a0`` on the free DOFs, ready to factorise.

        Returns ``(A_uu, J, nu_free, blocks)``: the velocity block
        ``a0 rho M + eta K``, the reduced saddle-point matrix, the number of free
        velocities and the solver blocks (the form
        :class:`~skfem_granular.fluid.factor_cache.FactorCache` asks for).
        """
        A_uu = self.velocity_block(a0)
        return A_uu, self.reduced(self.linear_matrix(A_uu)), self.nu_free, self.solver_blocks(a0)

    def reduced(self, J: sp.spmatrix) -> sp.csr_matrix:
        """Restriction of a full matrix to the free DOFs."""
        J = sp.csr_matrix(J)
        return J[self.free][:, self.free]

    def _plus_convection(self, A: sp.csr_matrix, values: np.ndarray,
                         keep_zeros: bool = False) -> sp.csr_matrix:
        """``A + N`` for the values of ``N`` on the convection kernel's pattern (a superset
        of ``A``'s; ``values`` is overwritten).

        The same matrix as scipy's sparse sum (values ``a + n``, exact zeros dropped),
        without merging the two patterns on every call; with ``keep_zeros`` the exact
        zeros stay as stored entries, the kernel's pattern as it is (for products only:
        a factorisation's ordering would see them).
        """
        indices, indptr = self.space.convection.pattern
        pos = self._velocity_positions(A)
        if pos is None:
            return A + sp.csr_matrix((values, indices, indptr), shape=A.shape)
        from .pattern_numba import add_at_positions

        data = values
        add_at_positions(data, pos, A.data)  # data[pos] = A.data + data[pos]
        if keep_zeros:
            return sp.csr_matrix((data, indices, indptr), shape=A.shape)
        keep = data != 0
        if keep.all():
            return sp.csr_matrix((data, indices, indptr), shape=A.shape)
        kept = np.concatenate(([0], np.cumsum(keep)))
        return sp.csr_matrix((data[keep], indices[keep], kept[indptr].astype(indptr.dtype)),
                             shape=A.shape)

    def jacobian(self, x: np.ndarray, c_mass: float = 0.0, newton: bool = True,
                 w_mesh: np.ndarray | None = None) -> sp.csr_matrix:
        """Full Jacobian of :meth:`residual` at ``x`` (Picard matrix if ``newton=False``);
        with ``w_mesh`` that of the ALE form (the wind ``u - w``: ``- rho N(w)`` added)."""
        return self.linear_matrix(self.velocity_jacobian(x, c_mass, newton, w_mesh), x)

    def velocity_jacobian(self, x: np.ndarray, c_mass: float = 0.0, newton: bool = True,
                          w_mesh: np.ndarray | None = None,
                          keep_zeros: bool = False) -> sp.csr_matrix:
        """The velocity block of :meth:`jacobian` (without user terms): ``c rho M + eta K``
        and the linearised convection (Oseen's ``rho N(u - w)`` with ``newton=False``);
        ``keep_zeros``: as :meth:`_plus_convection` (a matrix for products only)."""
        A = self.velocity_block(c_mass)
        # values on the kernel's one pattern: differences and sums entry by entry, as
        # scipy's sparse operations compute them (exact zeros dropped at the end), without
        # merging patterns (1000 grains: 2 s a difference, 2 s a sum); a Stokes operator
        # on a fixed mesh never builds the kernel
        u = x[: self.space.nu]
        values: np.ndarray | None = None
        if self.convection and w_mesh is not None and not newton:  # N(u) - N(w) = N(u - w)
            values = self.space.convection.jacobian_data(u - w_mesh, newton=False)
        else:
            if self.convection:
                values = self.space.convection.jacobian_data(u, newton=newton)
            if w_mesh is not None:
                Nw = self.space.convection.jacobian_data(w_mesh, newton=False)
                values = -Nw if values is None else values - Nw
        if values is not None:
            values *= self.fluid.density
            A = self._plus_convection(A, values, keep_zeros)
        return A

    def reduced_jacobian(self, x: np.ndarray, c_mass: float = 0.0,
                         newton: bool = True) -> sp.csr_matrix:
        """``reduced(jacobian(x, c_mass, newton))`` on a pattern fixed per mesh.

        The free-DOF matrix is gathered straight from the values of the velocity block
        and of ``B``, ``B^T`` through an index map built once, without building and
        slicing the full matrix (entries that happen to vanish are kept as zeros).
        """
        if not self.convection or self.terms is not None:
            return self.reduced(self.jacobian(x, c_mass, newton))
        kern = self.space.convection
        A = self.velocity_block(c_mass)
        pos = self._velocity_positions(A)
        if pos is None:  # A not within the convection pattern: the general path
            return self.reduced(self.jacobian(x, c_mass, newton))
        indices, indptr, gather = self._reduced_pattern
        # the values of [velocity block | B^T | B] in one buffer, the velocity block
        # written in place (no separate copy to concatenate: 15 MB at 95k DOFs)
        nuu, nbt = kern.pattern[0].size, self._Bt.nnz
        values = np.empty(nuu + nbt + self._B_lower.nnz)
        data = kern.jacobian_data(x[: self.space.nu], newton=newton, out=values[:nuu])
        data *= self.fluid.density
        data[pos] += A.data
        values[nuu:nuu + nbt] = self._Bt.data
        values[nuu + nbt:] = self._B_lower.data
        values = values[gather]
        n = self.free.size
        return sp.csr_matrix((values, indices, indptr), shape=(n, n))

    def _velocity_positions(self, A: sp.csr_matrix) -> np.ndarray | None:
        """Positions of ``A``'s entries in the convection pattern (cached per pattern of
        ``A``: its index arrays, which the cache holds instead of ``A``)."""
        kern = self.space.convection
        held = self._conv_positions[0]
        if (held is None or held[0] is not A.indices or held[1] is not A.indptr
                or held[2] is not kern.pattern[0]):
            pos = None
            if A.has_canonical_format and A.shape == (self.space.nu, self.space.nu):
                from .pattern_numba import positions_in

                indices, indptr = kern.pattern
                # one merge of the two sorted rows each (compiled): as searchsorted of the
                # row-major keys, without sorting them
                pos = np.empty(A.indices.size,
                               dtype=np.int32 if indices.size < 2**31 - 1 else np.int64)
                if not positions_in(indptr, indices, A.indptr, A.indices, pos):
                    pos = None
            held = self._conv_positions[0] = (A.indices, A.indptr, kern.pattern[0], pos)
        return held[3]

    @cached_property
    def _reduced_pattern(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pattern of the reduced Newton matrix and where its values come from.

        The full matrix is built once with entry numbers as values; restricting it
        to the free DOFs carries them along.
        """
        indices, indptr = self.space.convection.pattern
        nuu, nbt, nb = indices.size, self._Bt.nnz, self._B_lower.nnz
        ids = np.arange(1, nuu + nbt + nb + 1, dtype=float)
        nu = self.space.nu
        Kp = sp.csr_matrix((ids[:nuu], indices, indptr), shape=(nu, nu))
        Bt = sp.csr_matrix((ids[nuu:nuu + nbt], self._Bt.indices, self._Bt.indptr),
                           shape=self._Bt.shape)
        Bl = sp.csr_matrix((ids[nuu + nbt:], self._B_lower.indices, self._B_lower.indptr),
                           shape=self._B_lower.shape)
        full = sp.vstack([sp.hstack([Kp, Bt], format="csr"), Bl], format="csr")
        R = self.reduced(full)
        R.sort_indices()
        gather = np.rint(R.data).astype(np.int64) - 1
        index = np.int32 if ids.size < 2**31 - 1 else np.int64
        return R.indices.copy(), R.indptr.copy(), gather.astype(index)

    # residuals ----------------------------------------------------------------
    def residual(self, x: np.ndarray, c_mass: float = 0.0, rhs_u: np.ndarray | None = None,
                 A_uu: sp.spmatrix | None = None, w_mesh: np.ndarray | None = None) -> np.ndarray:
        """Full residual ``R(x)``; ``rhs_u`` is added to the body force.

        ``w_mesh`` (velocity DOFs) is the mesh velocity of a moving mesh: the convection
        term becomes the ALE form ``rho ((u - w) . grad) u`` (``-rho (w . grad) u`` for
        Stokes: the time derivative is taken at moving nodes).
        """
        sp_ = self.space
        u, p = sp_.split(x)
        A = self.velocity_block(c_mass) if A_uu is None else A_uu
        ru = A @ u + self._Bt @ p - self.f
        if rhs_u is not None:
            ru = ru - rhs_u
        if w_mesh is not None:  # ALE: relative to the moving mesh, also for Stokes
            ru = ru + self.fluid.density * sp_.convection.apply_relative(u, w_mesh,
                                                                        self.convection)
        elif self.convection:
            ru = ru + self.fluid.density * sp_.convection.residual(u)
        rp = sp_.B @ u
        ub = self.user_blocks(x)
        if ub is not None:
            ru, rp = _plus_user(ub, u, ru, rp, rhs=True)
        return np.concatenate([ru, rp])

    def jacobian_action(self, x: np.ndarray, dx: np.ndarray, A_uu: sp.spmatrix,
                        w_mesh: np.ndarray | None = None) -> np.ndarray:
        """The Jacobian of :meth:`residual` at ``x`` applied to ``dx`` (full vectors), matrix-free.

        ``A_uu`` is the velocity block of the residual (``c rho M + eta K``). With
        convection the term is linearised at ``u``: ``rho (N(u - w) du + N(du) u)``;
        an ALE Stokes operator has ``-rho N(w) du``. Fixed DOFs of ``dx`` should be zero.
        """
        sp_ = self.space
        u = x[: sp_.nu]
        du, dp = sp_.split(dx)
        ru = A_uu @ du + self._Bt @ dp
        rho = self.fluid.density
        if w_mesh is None:
            if self.convection:
                ru += rho * sp_.convection.jacobian_action(u, du)
        elif self.convection:
            ru += rho * sp_.convection.relative_jacobian_action(u, w_mesh, du)
        else:
            ru += rho * sp_.convection.apply(-w_mesh, du)
        rp = sp_.B @ du
        ub = self.user_blocks(x)
        if ub is not None:
            ru, rp = _plus_user(ub, du, ru, rp, rhs=False)
        return np.concatenate([ru, rp])

    def apply_dirichlet(self, x: np.ndarray, t: float | None = None) -> np.ndarray:
        """Write the boundary values (and the pinned pressure) into ``x``."""
        d = self.dirichlet.dofs
        x[d] = self.dirichlet.values(t)[d]
        if self.pinned:
            x[self.space.nu] = 0.0
        return x

    def normalize_pressure(self, x: np.ndarray) -> np.ndarray:
        """Shift the pressure of a closed domain to zero mean (in place)."""
        if self.pinned:
            sp_ = self.space
            p = x[sp_.nu:]
            w = self._pressure_weights
            p -= (w @ p) / w.sum()
        return x

    @cached_property
    def _pressure_weights(self) -> np.ndarray:
        return np.asarray(self.space.Mp.sum(axis=0)).ravel()

    def solver_blocks(self, c_mass: float = 0.0) -> dict:
        """Extra blocks for the solvers (preconditioners, ordering), on the free DOFs.

        The blocks are built once per operator and shared: do not modify them.
        """
        # the pressure Laplacian only serves the Krylov solver's Schur approximation of a
        # time step (a0 rho Lp^-1); a steady solve never builds it (nor the basis it needs)
        Lp = self._free_pressure_laplace if c_mass > 0 else None
        return dict(Mp=self._free_pressure_mass, Lp=Lp, eta=self.fluid.viscosity,
                    a0rho=c_mass * self.fluid.density, ordering=self.ordering)

    @cached_property
    def _free_pressure_mass(self) -> sp.csr_matrix:
        """Pressure mass matrix restricted to the free pressures."""
        pfree = self.free[self.nu_free:] - self.space.nu
        return self.space.Mp[pfree][:, pfree]

    @cached_property
    def _free_pressure_laplace(self) -> sp.csr_matrix:
        """Pressure Laplace matrix restricted to the free pressures."""
        pfree = self.free[self.nu_free:] - self.space.nu
        return self.space.Lp[pfree][:, pfree]

    @cached_property
    def ordering(self) -> np.ndarray:
        """Fill-reducing ordering of the free DOFs, computed once for the direct solvers."""
        return self.space.ordering(self.free)


def _plus_user(ub: UserBlocks, u: np.ndarray, ru: np.ndarray, rp: np.ndarray,
               rhs: bool) -> tuple[np.ndarray, np.ndarray]:
    """The momentum and continuity rows with the user terms' matrices applied to ``u``
    added (and, with ``rhs``, their right-hand sides subtracted)."""
    if ub.A is not None:
        ru = ru + ub.A @ u
    if ub.C is not None:
        rp = rp + ub.C @ u
    if rhs and ub.b is not None:
        ru = ru - ub.b
    if rhs and ub.g is not None:
        rp = rp - ub.g
    return ru, rp
