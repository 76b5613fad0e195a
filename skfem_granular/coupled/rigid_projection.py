"""The split coupling's pressure projection, the grains' rigid velocities inside it.

With ``H = LUMPING rho diag(M)`` on the free velocity DOFs, ``C = B E_Gamma`` (the
pressure's coupling to the rigid modes of the outlines) and ``M_eff = M_b + E_Gamma^T H
E_Gamma`` (each grain's mass and inertia with the fluid's lumped on its outline), the
projection solves the symmetric quasi-definite system::

    [ B_i H_i^-1 B_i^T   C      ] [psi]   [r]
    [ C^T               -M_eff  ] [ y ] = [0]

for the divergence ``r`` of a predicted velocity. It does not depend on the step, so
:class:`RigidProjection` factorises it once per mesh and, while the mesh moves, uses the
factors as the preconditioner of GMRES on the moved mesh's operator (products with
``B``, ``B^T`` and ``E``; no matrix is built per step).
"""

from __future__ import annotations

import time
import weakref

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..fluid.errors import ConvergenceError
from ..fluid.ordering import minimum_degree

#: The projection's velocity mass ``H = LUMPING rho diag(M)``: the pressure
#: extrapolation of second order is stable for ``H`` below about ``0.5-0.9 diag(M)`` and
#: unstable for the row-sum and HRZ lumpings (design page, measured).
LUMPING = 0.85


class RigidProjection:
    """The projection of a split coupling, on the mesh the coupling is on.

    Parameters
    ----------
    coupling : ReducedRigid
        The coupling (its space, prolongation ``E``, free DOFs, masses and timings are
        read at every call: a moved mesh is the coupling's current one).
    rtol, max_iterations, refactor_after
        GMRES on a moved mesh: relative residual, iteration limit, and the iterations
        above which :attr:`refactor_due` asks for new factors
        (:class:`~skfem_granular.coupled.split.SplitOptions`).
    """

    def __init__(self, coupling, rtol: float, max_iterations: int, refactor_after: int):
        # a proxy: coupling -> projection -> coupling would be a reference cycle, and a
        # remeshed-away coupling (its space, blocks and these factors) would stay in memory
        # until Python's cyclic collector ran (measured: +350-400 MB a remesh, 200 grains)
        self.coupling = weakref.proxy(coupling)
        self.rtol, self.max_iterations, self.refactor_after = rtol, max_iterations, refactor_after
        self._ordering: np.ndarray | None = None
        # (LU, vertices it was made on, centres there)
        self._factors: tuple[spla.SuperLU, np.ndarray, np.ndarray] | None = None
        #: A step's GMRES needed more than ``refactor_after`` iterations.
        self.refactor_due = False
        self.factorizations = 0
        self.iterations = 0

    # ------------------------------------------------------------------ state
    def forget(self) -> None:
        """Factorise anew on the next solve."""
        self._factors = None

    def record(self) -> tuple[np.ndarray, np.ndarray] | None:
        """``(vertices, centres)`` where the factors held were made (None: none)."""
        return None if self._factors is None else (self._factors[1], self._factors[2])

    # ------------------------------------------------------------------ the system
    def lumped_mass(self) -> np.ndarray:
        """``H``: the velocity mass on the coupling's current mesh (velocity DOFs)."""
        c = self.coupling
        return LUMPING * c.fluid.density * c.space.M.diagonal()

    def _rigid_blocks(self, H: np.ndarray):
        """``E_Gamma`` (velocity rows, rigid columns) and ``M_eff``."""
        c = self.coupling
        E_G = c.E[: c.space.nu, c.rigid_slice]
        return E_G, (E_G.T @ sp.diags(H) @ E_G + sp.diags(c.inertia_diag())).tocsr()

    def matrix(self) -> sp.csr_matrix:
        """The projection's matrix on the coupling's current mesh."""
        c = self.coupling
        H = self.lumped_mass()
        B = sp.csr_matrix(c.space.B)[c.p_free - c.space.nu]
        E_G, M_eff = self._rigid_blocks(H)
        B_i = B[:, c.u_free]
        S = B_i @ sp.diags(1.0 / H[c.u_free]) @ B_i.T
        C = (B @ E_G).tocsr()
        return sp.bmat([[S, C], [C.T, -M_eff]], format="csr")

    def operator(self) -> spla.LinearOperator:
        """:meth:`matrix` as products with ``B``, ``B^T`` and ``E``."""
        c = self.coupling
        sp_ = c.space
        nu, nz, rig = sp_.nu, c.nz, c.rigid_slice
        H = self.lumped_mass()
        H_inv = np.zeros(nu)
        H_inv[c.u_free] = 1.0 / H[c.u_free]
        _, M_eff = self._rigid_blocks(H)
        B, B_T = sp_.B, sp_.B.T
        p_rows = c.p_free - nu
        n_p = p_rows.size

        def matvec(v):
            psi = np.zeros(sp_.N - nu)
            psi[p_rows] = v[:n_p]
            g = B_T @ psi
            z = np.zeros(nz)
            z[rig] = v[n_p:]
            top = (B @ (H_inv * g + (c.E @ z)[:nu]))[p_rows]
            bottom = (c.ET @ np.concatenate([g, np.zeros(sp_.N - nu)]))[rig] - M_eff @ v[n_p:]
            return np.concatenate([top, bottom])

        n = n_p + M_eff.shape[0]
        return spla.LinearOperator((n, n), matvec=matvec)

    def _ordering_of_graph(self) -> np.ndarray:
        """Minimum degree on the projection's graph: its unknowns (free pressures, rigid
        velocities) adjacent when they share a velocity DOF (once per mesh)."""
        if self._ordering is None:
            c = self.coupling
            nu = c.space.nu
            Bp = abs(sp.csr_matrix(c.space.B)[c.p_free - nu]).T.tocsr()
            E_G = abs(c.E[:nu, c.rigid_slice])
            self._ordering = minimum_degree(sp.hstack([Bp, E_G], format="csr"))
        return self._ordering

    # ------------------------------------------------------------------ solving
    def factorize(self) -> None:
        """Factorise the projection on the coupling's current mesh."""
        c = self.coupling
        t0 = time.perf_counter()
        P = self.matrix()
        perm = self._ordering_of_graph()
        lu = spla.splu(P[perm][:, perm].tocsc(), permc_spec="NATURAL", diag_pivot_thresh=0.0,
                       options=dict(SymmetricMode=True))
        self._factors = (lu, c.space.mesh.p.copy(), c.centers.copy())
        self.refactor_due = False
        self.factorizations += 1
        c.timings["factorization"] += time.perf_counter() - t0

    def _apply_factors(self, b: np.ndarray) -> np.ndarray:
        assert self._factors is not None and self._ordering is not None
        perm = self._ordering
        x = np.empty_like(b)
        x[perm] = self._factors[0].solve(np.ascontiguousarray(b[perm]))
        return x

    def solve(self, r: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(psi, y, H)``: the projection's solution for the divergence ``r`` (free
        pressures) on the coupling's current mesh, and the velocity mass ``H`` it used."""
        if self._factors is None:
            self.factorize()
        assert self._factors is not None
        c = self.coupling
        b = np.concatenate([r, np.zeros(c.nu_z - c.n_ufree)])
        if np.array_equal(self._factors[1], c.space.mesh.p):
            sol = self._apply_factors(b)
        else:  # a moved mesh: the held factors precondition the current operator
            pre = spla.LinearOperator((b.size, b.size), matvec=self._apply_factors)
            sol, its = krylov(spla.gmres, self.operator(), b, pre, self.rtol,
                              self.max_iterations, restart=30, callback_type="pr_norm")
            self.iterations += its
            self.refactor_due = its > self.refactor_after
        return sol[: r.size], sol[r.size:], self.lumped_mass()


def krylov(method, A, b, M, rtol: float, maxiter: int, strict: bool = True,
           **options) -> tuple[np.ndarray, int]:
    """``method`` (scipy's ``cg``, ``bicgstab`` or ``gmres``) from zero (or ``x0``);
    returns the solution and its iterations; raises ConvergenceError if it does not
    reach ``rtol`` (``strict``)."""
    its = [0]

    def count(_):
        its[0] += 1

    x, info = method(A, b, M=M, rtol=rtol, atol=0.0, maxiter=maxiter, callback=count,
                     **options)
    if info < 0 and np.linalg.norm(b - A @ x) <= rtol * np.linalg.norm(b):
        info = 0  # a breakdown (BiCGStab's) at a solution that already meets the tolerance
    if info != 0 and strict:
        raise ConvergenceError(f"split coupling: {method.__name__} did not converge in "
                               f"{its[0]} iterations")
    return x, its[0]
