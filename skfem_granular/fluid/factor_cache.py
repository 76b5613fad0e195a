"""The factorised BDF2 operator, kept while its coefficient ``a0`` stays the same.

Every time-dependent solver in the package (the fluid's :class:`BDF2Integrator`
and both fluid-particle couplings) factorises the linear part of its BDF2
corrector, ``a0 rho M + eta K`` with the divergence constraint, and reuses it as
the operator of a chord iteration for as long as the step size and the step
ratio, and with them ``a0``, do not change. :class:`FactorCache` is that rule in
one place: it asks its owner to assemble the matrix for a new ``a0``, factorises
it, and books assembly and factorisation times.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import scipy.sparse as sp


class FactorCache:
    """A linear solver factorised for one BDF2 coefficient ``a0`` at a time.

    Parameters
    ----------
    solver : SaddlePointSolver
        The solver that holds the factorisation.
    assemble : callable
        ``assemble(a0) -> (A_uu, J, nu, blocks)``: the velocity block
        ``a0 rho M + eta K`` (kept for residuals), the matrix to factorise,
        the number of its velocity-like unknowns (they come first), and the
        keyword arguments for :meth:`SaddlePointSolver.factorize`.
    timings : dict
        ``"assembly"`` and ``"factorization"`` entries are incremented.

    Examples
    --------
    >>> cache = FactorCache(solver, op.reduced_bdf2_system, timings)  # doctest: +SKIP
    >>> A_uu = cache.operator(a0)          # factorises on the first call only
    >>> dx = cache.solver.solve(-r_free)
    """

    def __init__(self, solver, assemble: Callable[[float], tuple], timings: dict):
        self.solver = solver
        self._assemble = assemble
        self.timings = timings
        self.a0: float | None = None
        self.A_uu: sp.csr_matrix | None = None
        self.factorizations = 0  # of the linear operator (a0 changed, or cleared)
        self.refreshes = 0  # factorisations of another system (factorize_system)
        #: chord iterations spent on the held factorisation beyond a fresh one's (ChordStall)
        self.extra_iterations = 0
        #: whether the factorisation held (or, after a remesh, the last one on the previous
        #: mesh) is of a Newton Jacobian rather than of the linear operator
        self.newton_operator = False

    def operator(self, a0: float) -> sp.csr_matrix:
        """Factorise for ``a0`` unless that is the factorisation held; returns ``A_uu``."""
        if self.a0 != a0:
            t0 = time.perf_counter()
            A_uu, J, nu, blocks = self._assemble(a0)
            t1 = time.perf_counter()
            self.solver.factorize(J, nu, **blocks)
            self.timings["assembly"] += t1 - t0
            self.timings["factorization"] += time.perf_counter() - t1
            self.A_uu = A_uu
            self.a0 = a0
            self.factorizations += 1
            self.extra_iterations = 0
            self.newton_operator = False
        return self.A_uu

    def factorize_system(self, a0: float, system: tuple) -> sp.csr_matrix:
        """Factorise ``system`` (what ``assemble`` returns, e.g. a Newton Jacobian instead of
        the BDF2-Stokes matrix) and hold it for ``a0``: a chord iteration that stalls on the
        linear operator continues on it, and later steps with the same ``a0`` reuse it.
        Returns ``A_uu``."""
        t0 = time.perf_counter()
        A_uu, J, nu, blocks = system
        self.solver.factorize(J, nu, **blocks)
        self.timings["factorization"] += time.perf_counter() - t0
        self.refreshes += 1
        self.extra_iterations = 0
        self.newton_operator = True
        self.A_uu, self.a0 = A_uu, a0
        return A_uu

    def clear(self) -> None:
        """Forget the factorisation (and its kind): the next :meth:`operator` call
        factorises anew."""
        self.a0 = None
        self.extra_iterations = 0
        self.newton_operator = False
