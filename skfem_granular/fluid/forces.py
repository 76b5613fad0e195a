"""Fluid force and torque on a named boundary (paper Eq. 3).

Two evaluations:

- :func:`traction_force`: ``F = -int_Gamma sigma n dl`` with
  ``sigma = -p I + eta (grad u + grad u^T)`` and ``n`` the facet normal of
  scikit-fem, which on a hole points *into* the particle (out of the fluid);
  the minus sign turns it into the paper's normal pointing into the fluid.
- :func:`consistent_force`: the momentum residual of the discrete system
  tested with the function that is ``e_i`` on the boundary's DOFs (the
  variational "reaction" force). It converges faster than the traction
  integral and is what a rigid-body coupling sees.

Both return the force *exerted by the fluid on the boundary*.
"""

from __future__ import annotations

import numpy as np
from skfem import Functional, asm
from skfem.helpers import grad

from .._validate import finite_vector


def rigid_lever(space, dofs: np.ndarray, center) -> np.ndarray:
    """Values of ``e_z x (x - X)`` at the velocity DOFs ``dofs`` (the rotation's lever arm).

    The x component of a DOF gets ``-(y - Y)``, the y component ``x - X``: a
    rigid rotation ``omega`` about ``center`` has the DOF values ``omega`` times these.
    """
    X, Y = finite_vector("center", center)
    locs = space.velocity_doflocs[:, dofs]
    comp = space.component[dofs]
    return np.where(comp == 0, -(locs[1] - Y), locs[0] - X)


def consistent_force(space, residual_u: np.ndarray, name: str) -> np.ndarray:
    """Reaction force ``(Fx, Fy)`` on boundary ``name`` from the momentum residual."""
    dofs = space.boundary_dofs(name)
    comp = space.component[dofs]
    r = residual_u[dofs]
    return -np.array([r[comp == 0].sum(), r[comp == 1].sum()])


def consistent_torque(space, residual_u: np.ndarray, name: str, center) -> float:
    """Reaction torque about ``center`` on boundary ``name``."""
    dofs = space.boundary_dofs(name)
    return -float(residual_u[dofs] @ rigid_lever(space, dofs, center))


def _stress_fields(space, fluid, u, p, name):
    fb = space.facet_basis(name, "velocity")
    fbp = space.facet_basis(name, "pressure")
    return fb, dict(u=fb.interpolate(u), p=fbp.interpolate(p))


def _traction(w):
    """Traction on the boundary body: ``-sigma n`` (``n`` out of the fluid), ``(2, ...)``."""
    n = w.n
    G = grad(w["u"])
    s = w["eta"] * (G + np.transpose(G, (1, 0, 2, 3)))
    return -np.array([-w["p"] * n[0] + s[0, 0] * n[0] + s[0, 1] * n[1],
                      -w["p"] * n[1] + s[1, 0] * n[0] + s[1, 1] * n[1]])


@Functional
def _traction_x(w):
    return _traction(w)[0]


@Functional
def _traction_y(w):
    return _traction(w)[1]


@Functional
def _traction_torque(w):
    tx, ty = _traction(w)
    return (w.x[0] - w["X"]) * ty - (w.x[1] - w["Y"]) * tx


def traction_force(space, fluid, u: np.ndarray, p: np.ndarray, name: str) -> np.ndarray:
    """Force ``(Fx, Fy)`` on boundary ``name`` by integrating the traction."""
    fb, fields = _stress_fields(space, fluid, u, p, name)
    return np.array([asm(_traction_x, fb, eta=fluid.viscosity, **fields),
                     asm(_traction_y, fb, eta=fluid.viscosity, **fields)])


def traction_torque(space, fluid, u: np.ndarray, p: np.ndarray, name: str, center) -> float:
    """Torque about ``center`` on boundary ``name`` by integrating the traction."""
    X, Y = finite_vector("center", center)
    fb, fields = _stress_fields(space, fluid, u, p, name)
    return float(asm(_traction_torque, fb, eta=fluid.viscosity, X=X, Y=Y, **fields))
