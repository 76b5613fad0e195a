"""The discrete Navier-Stokes operator on one mesh for one set of boundary data.

``R(x) = [ (c rho M + eta K) u + rho N(u) u + B^T p - f ;  B u ]`` with
``x = [u, p]``; ``c = 0`` for steady problems and ``c = a0`` inside a BDF2
step (the history goes into ``f``). Dirichlet velocity DOFs (and, in closed
domains, one pinned pressure DOF) are eliminated: solvers act on the free
DOFs only while the fixed ones hold their prescribed values in ``x``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .boundary import DirichletData
from .properties import Fluid
from .space import TaylorHood


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

    Notes
    -----
    Pressure in a closed domain is defined up to a constant: the first
    pressure DOF is pinned to zero during the solve and the result is then
    shifted to zero mean over the domain (:meth:`normalize_pressure`).
    """

    def __init__(self, space: TaylorHood, fluid: Fluid, dirichlet: DirichletData,
                 convection: bool = False, viscous: str = "auto", body_force=None):
        if not isinstance(fluid, Fluid):
            raise ValueError(f"fluid: a skfem_granular.Fluid is required, got {type(fluid).__name__}")
        self.space = space
        self.fluid = fluid
        self.dirichlet = dirichlet
        self.convection = bool(convection)
        if viscous == "auto":
            viscous = "symmetric" if dirichlet.closed else "laplace"
        self.viscous = viscous
        self.K = fluid.viscosity * space.K(viscous)
        self.f = self._body_force(body_force)
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
            val = np.array([np.broadcast_to(fx, x[0].shape), np.broadcast_to(fy, x[0].shape)], float)
        else:
            c = evaluate(body_force, np.zeros(1), np.zeros(1), None, "body_force")[:, 0]
            val = np.broadcast_to(c[:, None, None], (2,) + sp_.ub.dx.shape)
        if not np.all(np.isfinite(val)):
            raise ValueError("body_force: contains NaN or inf")
        return asm(form, sp_.ub, f=val)

    # blocks -----------------------------------------------------------------
    def velocity_block(self, c_mass: float = 0.0) -> sp.csr_matrix:
        """Linear velocity block ``c rho M + eta K``."""
        if c_mass == 0.0:
            return self.K
        return (c_mass * self.fluid.density) * self.space.M + self.K

    def matrix(self, A_uu: sp.spmatrix) -> sp.csr_matrix:
        """Full saddle-point matrix ``[[A, B^T], [B, 0]]``."""
        B = self.space.B
        return sp.bmat([[A_uu, B.T], [B, self._zero_p]], format="csr")

    def reduced(self, J: sp.spmatrix) -> sp.csr_matrix:
        """Restriction of a full matrix to the free DOFs."""
        J = sp.csr_matrix(J)
        return J[self.free][:, self.free]

    def jacobian(self, x: np.ndarray, c_mass: float = 0.0, newton: bool = True) -> sp.csr_matrix:
        """Full Jacobian of :meth:`residual` at ``x`` (Picard matrix if ``newton=False``)."""
        A = self.velocity_block(c_mass)
        if self.convection:
            u = x[: self.space.nu]
            A = A + self.fluid.density * self.space.convection.jacobian(u, newton=newton)
        return self.matrix(A)

    # residuals ----------------------------------------------------------------
    def residual(self, x: np.ndarray, c_mass: float = 0.0, rhs_u: np.ndarray | None = None,
                 A_uu: sp.spmatrix | None = None) -> np.ndarray:
        """Full residual ``R(x)``; ``rhs_u`` is added to the body force."""
        sp_ = self.space
        u, p = sp_.split(x)
        A = self.velocity_block(c_mass) if A_uu is None else A_uu
        ru = A @ u + sp_.B.T @ p - self.f
        if rhs_u is not None:
            ru = ru - rhs_u
        if self.convection:
            ru = ru + self.fluid.density * sp_.convection.residual(u)
        return np.concatenate([ru, sp_.B @ u])

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
            w = np.asarray(sp_.Mp.sum(axis=0)).ravel()
            p -= (w @ p) / w.sum()
        return x

    def solver_blocks(self, c_mass: float = 0.0) -> dict:
        """Extra blocks for the Krylov preconditioner, restricted to free DOFs."""
        sp_ = self.space
        pfree = self.free[self.nu_free:] - sp_.nu
        Mp = sp_.Mp[pfree][:, pfree]
        Lp = sp_.Lp[pfree][:, pfree]
        return dict(Mp=Mp, Lp=Lp, eta=self.fluid.viscosity, a0rho=c_mass * self.fluid.density)
