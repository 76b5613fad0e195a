"""User terms: scikit-fem forms added to the momentum and continuity equations.

The built-in blocks (``M``, ``K``, ``B``, the convection) come from compiled kernels
(:mod:`~skfem_granular.fluid.geometry`); :class:`UserTerms` is where a user adds
terms of their own, written as ordinary scikit-fem forms::

    from skfem import BilinearForm, LinearForm
    from skfem.helpers import dot

    @BilinearForm
    def drag(u, v, w):            # Brinkman drag alpha u . v
        return alpha * dot(u, v)

    @LinearForm
    def force(v, w):              # a body force f(x, t)
        return w.t * w.x[0] * v[1]

    terms = UserTerms(momentum=[drag, force])
    solve_steady(mesh, fluid, {...}, terms=terms)

The equations solved become::

    momentum:    (built-in terms)(u, p; v) + sum a_i(u, v) = (f, v) + sum l_i(v)
    continuity:  -(q, div u)               + sum c_i(u, q) =          sum g_i(q)

with ``a_i``, ``l_i`` the momentum forms (velocity test functions ``v``, P2 vector
basis; a bilinear form's trial function is the velocity) and ``c_i``, ``g_i`` the
continuity forms (pressure test functions ``q``, P1 basis; a bilinear form's trial
function is the velocity). A mass source ``div u = s`` is the continuity form
``g(q) = -(s, q)``.

Every form is assembled with scikit-fem's ``asm`` on the current mesh (the moved mesh
of an ALE step, at each iterate), with these entries of ``w``: ``w.x`` the quadrature
points, ``w["t"]`` the time (the end of the step; 0 for a steady solve) and
``w["u"]`` the current velocity (a ``DiscreteField``: ``w["u"][0]``, ``w["u"].grad``).
Bilinear forms enter the system matrix and so the Newton Jacobian, with their
coefficients frozen at the current iterate (a form whose coefficient reads ``w["u"]``
is linearised in its trial function only: Picard for that term).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from skfem import BilinearForm, LinearForm, asm

#: Where each equation's forms are tested, for messages.
_BASES = {"momentum": "the velocity (P2 vector) basis",
          "continuity": "the pressure (P1) basis (trial: the velocity)"}


@dataclass(frozen=True)
class UserBlocks:
    """User terms assembled at one state: ``A`` (nu, nu) and ``b`` (nu,) of the momentum
    equation, ``C`` (np, nu) and ``g`` (np,) of the continuity equation (``None``: no
    such term)."""

    A: sp.csr_matrix | None
    b: np.ndarray | None
    C: sp.csr_matrix | None
    g: np.ndarray | None


class UserTerms:
    """scikit-fem forms added to the fluid equations (module notes: the equations).

    Parameters
    ----------
    momentum : BilinearForm, LinearForm or a sequence of them
        Terms tested with the velocity (P2 vector basis): a ``BilinearForm(u, v, w)``
        (trial: the velocity) is added to the left-hand side, a ``LinearForm(v, w)``
        to the right-hand side (a force density, N/m^3).
    continuity : BilinearForm, LinearForm or a sequence of them
        Terms tested with the pressure (P1 basis): a ``BilinearForm(u, q, w)``
        (trial: the velocity) is added to ``-(q, div u)``, a ``LinearForm(q, w)`` to
        the right-hand side.

    Raises
    ------
    ValueError
        One line naming the term, when it is not a scikit-fem ``BilinearForm`` or
        ``LinearForm``, or cannot be assembled on its basis (its integrand is not one
        value per quadrature point there: a scalar form given as a momentum term, say).

    Examples
    --------
    >>> from skfem import BilinearForm
    >>> from skfem.helpers import dot
    >>> drag = BilinearForm(lambda u, v, w: 2.0 * dot(u, v))
    >>> UserTerms(momentum=[drag])
    UserTerms(momentum=1, continuity=0)
    """

    def __init__(self, momentum=(), continuity=()):
        self.momentum = _as_forms("momentum", momentum)
        self.continuity = _as_forms("continuity", continuity)
        _probe(self)

    def __repr__(self) -> str:
        return f"UserTerms(momentum={len(self.momentum)}, continuity={len(self.continuity)})"

    def assemble(self, space, u: np.ndarray, t: float) -> UserBlocks:
        """The terms on ``space`` (a :class:`~skfem_granular.fluid.TaylorHood`, moved or
        not) at the velocity DOFs ``u`` and time ``t``."""
        ub, pb = space.ub, space.pb
        w = {"u": ub.interpolate(u), "t": float(t)}
        A, b = _sum(self.momentum, ub, ub, w)
        C, g = _sum(self.continuity, ub, pb, w)
        return UserBlocks(A, b, C, g)


def _as_forms(field: str, forms) -> tuple:
    """The forms of one equation as a tuple, each checked to be a BilinearForm or LinearForm."""
    if isinstance(forms, (BilinearForm, LinearForm)):
        forms = (forms,)
    if not isinstance(forms, Sequence) or isinstance(forms, str):
        raise ValueError(f"UserTerms.{field}: must be a skfem BilinearForm or LinearForm or a "
                         f"list of them, got {type(forms).__name__}")
    for i, f in enumerate(forms):
        if not isinstance(f, (BilinearForm, LinearForm)):
            raise ValueError(f"UserTerms.{field}[{i}]: must be a skfem BilinearForm or "
                             f"LinearForm, got {type(f).__name__}")
    return tuple(forms)


def _sum(forms, trial, test, w):
    """The sums of the bilinear forms (matrix, test rows) and linear forms (vector)."""
    A = b = None
    for f in forms:
        if isinstance(f, BilinearForm):
            M = asm(f, trial, test, **w).tocsr()
            A = M if A is None else A + M
        else:
            v = asm(f, test, **w)
            b = v if b is None else b + v
    return A, b


def _probe(terms: UserTerms) -> None:
    """Assemble every form once on a two-triangle mesh, its integrand's shape checked."""
    from skfem import Basis, ElementTriP1, ElementTriP2, ElementVector, MeshTri

    ub = Basis(MeshTri(), ElementVector(ElementTriP2()), intorder=4)
    pb = ub.with_element(ElementTriP1())
    w = {"u": ub.interpolate(np.zeros(ub.N)), "t": 0.0}
    for field, test in (("momentum", ub), ("continuity", pb)):
        for i, f in enumerate(getattr(terms, field)):
            name = f"UserTerms.{field}[{i}]"
            checked = type(f)(_shape_checked(f.form, test.X.shape[1], name, field))
            try:
                with np.errstate(all="ignore"):
                    if isinstance(f, BilinearForm):
                        asm(checked, ub, test, **w)
                    else:
                        asm(checked, test, **w)
            except ValueError as exc:
                if str(exc).startswith(name):
                    raise
                raise ValueError(f"{name}: cannot be assembled on {_BASES[field]}: "
                                 f"{exc}") from None
            except (TypeError, IndexError, KeyError, AttributeError) as exc:
                raise ValueError(f"{name}: cannot be assembled on {_BASES[field]}: "
                                 f"{type(exc).__name__}: {exc}") from None


def _shape_checked(fn, nq: int, name: str, field: str):
    """``fn`` raising when its integrand is not one value per element and quadrature point."""

    def form(*args):
        val = np.asarray(fn(*args))
        if val.ndim not in (0, 2) or (val.ndim == 2 and val.shape[1] != nq):
            raise ValueError(f"{name}: the integrand has shape {val.shape}, not one value per "
                             f"element and quadrature point on {_BASES[field]} (a dot() or "
                             f"ddot() missing, or a form written for another basis?)")
        return val

    return form
