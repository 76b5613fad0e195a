"""Weak forms of the Taylor-Hood P2/P1 Navier-Stokes blocks.

Small module-level scikit-fem forms, as in ``skfem.models``. Material
parameters are applied by the caller (``K = eta * viscous_symmetric``), so
the constant blocks are assembled once per mesh.

Sign convention: the saddle-point system is ``[[A, B.T], [B, 0]]`` with
``B`` from :data:`divergence` (``b(u, q) = -(q, div u)``), which makes the
pressure the Lagrange multiplier of the incompressibility constraint
(Eq. 2 of the paper).
"""

from __future__ import annotations

from skfem import BilinearForm, LinearForm
from skfem.helpers import ddot, div, dot, grad, mul, sym_grad


@BilinearForm
def vector_mass(u, v, w):
    """``M``: ``(u, v)``."""
    return dot(u, v)


@BilinearForm
def viscous_symmetric(u, v, w):
    """``K / eta``, symmetric-gradient form: ``2 (eps(u), eps(v))``."""
    return 2.0 * ddot(sym_grad(u), sym_grad(v))


@BilinearForm
def viscous_laplace(u, v, w):
    """``K / eta``, Laplacian form: ``(grad u, grad v)``.

    Equivalent to :data:`viscous_symmetric` when every boundary carries
    Dirichlet data; its natural boundary condition is the "do-nothing"
    outflow ``eta du/dn - p n = 0``.
    """
    return ddot(grad(u), grad(v))


@BilinearForm
def divergence(u, q, w):
    """``B``: ``-(q, div u)``, trial velocity, test pressure."""
    return -div(u) * q


@BilinearForm
def pressure_mass(p, q, w):
    """Pressure mass matrix ``Mp``: ``(p, q)``."""
    return p * q


@BilinearForm
def pressure_laplace(p, q, w):
    """Pressure Laplacian ``Lp``: ``(grad p, grad q)``."""
    return dot(grad(p), grad(q))


@BilinearForm
def convection(u, v, w):
    """``N(w)``: ``((w . grad) u, v)`` with the wind ``w['wind']``."""
    return dot(mul(grad(u), w["wind"]), v)


@BilinearForm
def convection_newton(u, v, w):
    """Newton linearisation of the convection term at ``w['wind']``.

    ``((w . grad) du + (du . grad) w, v)``; together with ``N(w) w`` on the
    right-hand side it is the Jacobian of ``N(u) u``.
    """
    return dot(mul(grad(u), w["wind"]) + mul(grad(w["wind"]), u), v)


@LinearForm
def body_force(v, w):
    """``(f, v)`` with the force density ``w['f']`` (N/m^3)."""
    return dot(w["f"], v)
