"""The divergence-free projection applied to fields interpolated onto a new mesh."""

import numpy as np
import pytest
from helpers import annulus

import skfem_granular as sg
from skfem_granular.fluid.boundary import DirichletData
from skfem_granular.fluid.operator import NavierStokesOperator
from skfem_granular.fluid.projection import divergence_free_projection


def _setup():
    space = sg.TaylorHood(annulus(1e-3, 2e-3, 32, 64, (8e-5) ** 2))
    bc = {"inner": (0.0, 1e-2), "outer": (0.0, 0.0)}
    op = NavierStokesOperator(space, sg.Fluid(1000.0, 1e-3), DirichletData(space, bc))
    x = op.apply_dirichlet(np.zeros(space.N))
    X = space.velocity_doflocs
    u = x[: space.nu] + 1e-3 * np.sin(3e3 * X[0]) * np.cos(2e3 * X[1])
    u[op.dirichlet.dofs] = x[op.dirichlet.dofs]
    return space, op, u


def _D_norm(space, v):
    return float(np.sqrt(v @ (space.M.diagonal() * v)))


def test_projection_is_divergence_free_keeps_boundary_values_and_is_idempotent():
    space, op, u = _setup()
    div0 = np.abs(space.B @ u).max()
    v = divergence_free_projection(op, u)
    assert np.abs(space.B @ v).max() <= 1e-10 * div0  # B v = 0 to round-off
    d = op.dirichlet.dofs
    assert np.array_equal(v[d], u[d])
    w = divergence_free_projection(op, v)
    assert np.abs(w - v).max() <= 1e-12 * np.abs(v).max()


def test_projection_is_the_nearest_divergence_free_field():
    # v = P(u) is divergence-free with u's boundary values; any other such field is
    # farther from u in the diag(M)-norm, e.g. P(v + e) for an interior perturbation e
    space, op, u = _setup()
    v = divergence_free_projection(op, u)
    rng = np.random.default_rng(1)
    e = np.zeros(space.nu)
    interior = np.setdiff1d(np.arange(space.nu), op.dirichlet.dofs)
    e[interior] = 1e-4 * rng.standard_normal(interior.size)
    other = divergence_free_projection(op, v + e)  # divergence-free, same boundary values
    assert np.abs(space.B @ other).max() <= 1e-10 * np.abs(space.B @ u).max()
    assert _D_norm(space, u - v) <= _D_norm(space, u - other) * (1 + 1e-12)
    # the residual u - v is diag(M)-orthogonal to divergence-free interior fields
    assert abs((u - v) @ (space.M.diagonal() * (other - v))) <= 1e-9 * _D_norm(space, u - v) \
        * _D_norm(space, other - v)



def test_projection_on_a_moved_configuration_needs_no_moved_operator():
    """Projecting on a moved configuration of the operator's mesh (``space=``) builds only
    its ``M`` and ``B``, and gives what the moved operator's projection gives, bit for
    bit, divergence-free there."""
    space, op, u = _setup()
    p = space.mesh.p
    moved = space.moved(p * (1.0 + 0.02 * np.sin(5e3 * p[::-1])))
    v = divergence_free_projection(op, u, space=moved)
    assert "_moved_geometry" not in moved.__dict__  # K and the affine maps not built
    assert np.array_equal(v, divergence_free_projection(op.moved(space.moved(moved.mesh.p)), u))
    assert np.abs(moved.B @ v).max() <= 1e-10 * np.abs(moved.B @ u).max()
    with pytest.raises(ValueError, match="names: 'C' is not a geometric block"):
        moved.blocks(("M", "C"))


def test_ale_jacobian_is_the_derivative_of_the_ale_residual():
    # the Newton matrix the coupled corrector factorises when its chord stalls: R is
    # quadratic in u, so R(x + dx) - R(x) - J(x) dx = [rho N(du) du; 0] exactly (0 for Stokes)
    space, _, u = _setup()
    rho = 1000.0
    for convection in (True, False):
        bc = {"inner": (0.0, 1e-2), "outer": (0.0, 0.0)}
        op = NavierStokesOperator(space, sg.Fluid(rho, 1e-3), DirichletData(space, bc),
                                  convection=convection)
        rng = np.random.default_rng(2)
        w = 1e-2 * rng.standard_normal(space.nu)
        x = np.concatenate([u, rng.standard_normal(space.np_)])
        dx = 1e-3 * rng.standard_normal(space.N)
        J = op.jacobian(x, c_mass=1e4, w_mesh=w)
        diff = op.residual(x + dx, c_mass=1e4, w_mesh=w) - op.residual(x, c_mass=1e4, w_mesh=w)
        left = diff - J @ dx
        expected = np.zeros(space.N)
        if convection:
            du = dx[: space.nu]
            expected[: space.nu] = rho * space.convection.apply(du, du)
            assert np.abs(expected).max() > 1e-6 * np.abs(diff).max()  # a visible term
        assert np.abs(left - expected).max() <= 1e-9 * np.abs(diff).max()
