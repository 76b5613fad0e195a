"""The built-in blocks assembled by scikit-fem's ``asm`` from :mod:`~skfem_granular.fluid.forms`.

A :class:`~skfem_granular.fluid.space.TaylorHood` built with
``assembly="scikit-fem"`` takes its blocks from here instead of the compiled
kernels of :mod:`~skfem_granular.fluid.geometry` and
:mod:`~skfem_granular.fluid.convection`: every block, on every (moved) mesh, and
the convection at every iterate are ``asm`` of the forms on the space's own bases.
The values are written into the compiled path's sparsity patterns (the solvers and
moved operators rely on them), so the two paths give the same systems to round-off
and everything downstream is shared. A reference path (what the compiled kernels are
checked against), slower: see the user-forms page for the measured cost.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from skfem import asm

from . import forms
from .convection import ConvectionActions

#: The forms of the geometric blocks, and the basis pair each is assembled on.
BLOCK_FORMS = {"M": (forms.vector_mass, "uu"), "K_symmetric": (forms.viscous_symmetric, "uu"),
               "K_laplace": (forms.viscous_laplace, "uu"), "B": (forms.divergence, "pu")}


def on_pattern(A: sp.spmatrix, indices: np.ndarray, indptr: np.ndarray) -> np.ndarray:
    """The values of ``A`` at the entries of the CSR pattern ``(indices, indptr)`` (sorted
    rows; entries of the pattern that ``A`` does not store are 0).

    Raises
    ------
    ValueError
        When ``A`` has a nonzero outside the pattern.
    """
    A = sp.csr_matrix(A)
    A.sum_duplicates()
    n_rows, n_cols = A.shape
    keys_p = np.repeat(np.arange(n_rows, dtype=np.int64), np.diff(indptr)) * n_cols + indices
    keys_a = np.repeat(np.arange(n_rows, dtype=np.int64), np.diff(A.indptr)) * n_cols + A.indices
    pos = np.minimum(np.searchsorted(keys_p, keys_a), keys_p.size - 1)
    inside = keys_p[pos] == keys_a
    if not np.all(inside | (A.data == 0)):
        raise ValueError("on_pattern: the matrix has entries outside the pattern")
    data = np.zeros(keys_p.size)
    data[pos[inside]] = A.data[inside]
    return data


def block(space, name: str) -> sp.csr_matrix:
    """The geometric block ``name`` (``M``, ``K_symmetric``, ``K_laplace``, ``B``) of
    ``space`` by ``asm``, on the compiled path's pattern."""
    form, kind = BLOCK_FORMS[name]
    pattern = getattr(space.reference_blocks, kind)
    A = asm(form, space.ub) if kind == "uu" else asm(form, space.ub, space.pb)
    return pattern.csr(on_pattern(A, pattern.indices, pattern.indptr))


class FormsConvection(ConvectionActions):
    """The convection ``((a . grad) b, v)`` by ``asm`` of :data:`~.forms.convection` and
    :data:`~.forms.convection_newton`, with the interface of
    :class:`~skfem_granular.fluid.convection.ConvectionKernel`.

    Parameters
    ----------
    space : TaylorHood
        The discretisation (moved or not); its vector P2 basis ``ub`` is used.
    """

    def __init__(self, space):
        self.space = space
        self.nu = space.nu
        self._indices, self._indptr = space.velocity_pattern[1:]

    @property
    def pattern(self) -> tuple[np.ndarray, np.ndarray]:
        """``(indices, indptr)``: the velocity blocks' pattern, shared by every Jacobian."""
        return self._indices, self._indptr

    def _matrix(self, wind: np.ndarray, newton: bool) -> sp.csr_matrix:
        ub = self.space.ub
        form = forms.convection_newton if newton else forms.convection
        return asm(form, ub, wind=ub.interpolate(np.asarray(wind, dtype=float)))

    def _vector(self, a, ca, w, cw, b) -> np.ndarray:
        """``(((ca a - cw w) . grad) b, v_i)``."""
        return self._matrix(ca * np.asarray(a) - cw * np.asarray(w), False) @ b

    def apply(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Vector of ``((a . grad) b, v_i)`` for all test functions ``v_i``."""
        return self._matrix(a, False) @ b

    def jacobian(self, u: np.ndarray, newton: bool = True) -> sp.csr_matrix:
        """Newton (or Picard, ``newton=False``) matrix at ``u`` on :attr:`pattern`."""
        return sp.csr_matrix((self.jacobian_data(u, newton), self._indices, self._indptr),
                             shape=(self.nu, self.nu))

    def jacobian_data(self, u: np.ndarray, newton: bool = True,
                      out: np.ndarray | None = None) -> np.ndarray:
        """Values of :meth:`jacobian` on :attr:`pattern` (written into ``out`` if given)."""
        data = on_pattern(self._matrix(u, newton), self._indices, self._indptr)
        if out is None:
            return data
        out[:] = data
        return out
