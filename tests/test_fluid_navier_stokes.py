"""Steady Navier-Stokes: Kovasznay flow (validation case 5), Newton reports and failures."""

import numpy as np
import pytest
from skfem import Functional, MeshTri, asm

import skfem_granular as sg
from skfem_granular.fluid import ConvergenceError
from skfem_granular.fluid.convection import ConvectionKernel

RE = 40.0
LAM = RE / 2 - np.sqrt(RE**2 / 4 + 4 * np.pi**2)


def kovasznay(x, y):
    e = np.exp(LAM * x)
    return 1 - e * np.cos(2 * np.pi * y), LAM / (2 * np.pi) * e * np.sin(2 * np.pi * y)


def kovasznay_p(x, y):
    return (1 - np.exp(2 * LAM * x)) / 2


def _mesh(n):
    m = MeshTri.init_tensor(np.linspace(-0.5, 1.0, 3 * n + 1), np.linspace(-0.5, 1.5, 4 * n + 1))
    return m.with_boundaries({"all": lambda x: np.ones(x.shape[1], dtype=bool)})


@Functional
def _u_err2(w):
    ux, uy = kovasznay(*w.x)
    return (w["u"][0] - ux) ** 2 + (w["u"][1] - uy) ** 2


@Functional
def _p_err2(w):
    return (w["p"] - kovasznay_p(*w.x) - w["c"]) ** 2


@Functional
def _p_exact(w):
    return kovasznay_p(*w.x)


def _errors(flow):
    sp = flow.space
    area = np.ptp(sp.mesh.p[0]) * np.ptp(sp.mesh.p[1])
    c = -asm(_p_exact, sp.pb) / area  # flow.p has zero mean; exact p shifted accordingly
    eu = np.sqrt(asm(_u_err2, sp.ub, u=sp.ub.interpolate(flow.u)))
    ep = np.sqrt(asm(_p_err2, sp.pb, p=sp.pb.interpolate(flow.p), c=c))
    return eu, ep


def test_kovasznay_convergence_orders():
    eu, ep = [], []
    for n in (2, 4, 8):
        flow = sg.solve_steady(_mesh(n), sg.Fluid(1.0, 1 / RE), {"all": kovasznay},
                               convection=True)
        assert flow.report.residuals[-1] < 1e-10
        assert flow.report.iterations <= 8
        a, b = _errors(flow)
        eu.append(a)
        ep.append(b)
    order_u = np.log2(eu[-2] / eu[-1])
    order_p = np.log2(ep[-2] / ep[-1])
    assert order_u >= 2.7, eu
    assert order_p >= 1.8, ep
    assert eu[-1] < 1e-3


def test_newton_converges_quadratically():
    flow = sg.solve_steady(_mesh(4), sg.Fluid(1.0, 1 / RE), {"all": kovasznay}, convection=True)
    r = np.array(flow.report.residuals)
    # after the first (Stokes) step, each Newton step at least squares the residual
    # up to a constant: r_{k+1} <= C r_k^2 with C modest
    k = np.flatnonzero(r < 1e-2)[0]
    assert r[k + 1] <= 50 * r[k] ** 2 + 1e-13


def test_newton_failure_gives_clear_error():
    with pytest.raises(ConvergenceError, match="did not converge in 2 iterations"):
        sg.solve_steady(_mesh(2), sg.Fluid(1.0, 1e-4), {"all": kovasznay}, convection=True,
                        maxiter=2, continuation="off")
    # two Newton iterations reach no stage of the continuation either
    with pytest.raises(ConvergenceError, match="did not converge even at 1024 times the "
                                               "viscosity 0.0001 .continuation start."):
        sg.solve_steady(_mesh(2), sg.Fluid(1.0, 1e-4), {"all": kovasznay}, convection=True,
                        maxiter=2)


def test_navier_stokes_departs_from_stokes_linearly_in_reynolds():
    """With the same boundary data, NS - Stokes = O(Re): tenfold viscosity, tenfold smaller.

    Measured relative differences 1.3e-4, 1.3e-5, 1.3e-6 for nu = 1e2, 1e3, 1e4.
    """
    mesh = _mesh(2)
    diffs = []
    for nu in (1e2, 1e3, 1e4):
        fluid = sg.Fluid(1.0, nu)
        s = sg.solve_steady(mesh, fluid, {"all": kovasznay})
        n = sg.solve_steady(mesh, fluid, {"all": kovasznay}, convection=True)
        diffs.append(np.abs(s.u - n.u).max() / np.abs(s.u).max())
    ratios = np.array(diffs[:-1]) / np.array(diffs[1:])
    np.testing.assert_allclose(ratios, 10.0, rtol=0.02)
    assert 0 < diffs[-1] < 1e-5


@pytest.mark.parametrize("moved", [False, True])
def test_convection_kernel_equals_scikit_fem_forms(moved):
    """The compiled convection vectors (plain, ALE-relative, Newton action) and the
    Jacobian matrix equal scikit-fem's assembly of ``forms.convection`` and
    ``forms.convection_newton`` to round-off, on a mesh and on that mesh moved."""
    import dataclasses

    from skfem import Basis, ElementTriP2, ElementVector

    from skfem_granular.fluid import forms

    mesh = MeshTri.init_tensor(np.linspace(0, 1, 7), np.linspace(0, 1, 6))
    space = sg.TaylorHood(mesh)
    if moved:
        p = mesh.p.copy()
        p += 0.04 * np.sin(np.pi * p[0]) * np.sin(np.pi * p[1]) * np.array([[1.0], [0.6]])
        space = space.moved(p)
        mesh = dataclasses.replace(mesh, doflocs=p)
    ub = Basis(mesh, ElementVector(ElementTriP2()), intorder=space.intorder)
    rng = np.random.default_rng(4)
    u, w, du = (rng.standard_normal(space.nu) for _ in range(3))
    kern = space.convection

    def N(wind):
        return asm(forms.convection, ub, wind=ub.interpolate(wind))

    scale = np.abs(N(u) @ u).max()
    assert np.abs(kern.residual(u) - N(u) @ u).max() <= 1e-13 * scale
    assert np.abs(kern.apply_relative(u, w) - N(u - w) @ u).max() <= 1e-13 * scale
    assert np.abs(kern.apply_relative(u, w, convection=False) + N(w) @ u).max() <= 1e-13 * scale
    J = asm(forms.convection_newton, ub, wind=ub.interpolate(u))
    assert np.abs(kern.jacobian_action(u, du) - J @ du).max() <= 1e-13 * scale
    # ALE: d/du of ((u - w) . grad) u is ((u - w) . grad) du + (du . grad) u
    J_rel = asm(forms.convection_newton, ub, wind=ub.interpolate(u)) - N(w)
    assert np.abs(kern.relative_jacobian_action(u, w, du) - J_rel @ du).max() <= 1e-13 * scale
    assert abs(kern.jacobian(u) - J).max() <= 1e-13 * abs(J).max()
    assert abs(kern.jacobian(u, newton=False) - N(u)).max() <= 1e-13 * abs(N(u)).max()


def test_convection_kernel_buffers_and_maps_are_checked():
    """Values written into a caller's buffer equal a new array's bit for bit; a buffer or
    a set of affine maps of the wrong shape is refused by name."""
    mesh = MeshTri.init_tensor(np.linspace(0, 1, 5), np.linspace(0, 1, 4))
    kern = sg.TaylorHood(mesh).convection
    u = np.random.default_rng(1).standard_normal(kern.nu)
    out = np.full(kern.pattern[0].size, 7.0)  # overwritten, not accumulated into
    assert kern.jacobian_data(u, out=out) is out
    np.testing.assert_array_equal(out, kern.jacobian_data(u))
    with pytest.raises(ValueError, match="out: "):
        kern.jacobian_data(u, out=np.zeros(3))
    with pytest.raises(ValueError, match=r"maps: shape \(2, 5\)"):
        kern.with_maps(np.zeros((2, 5)))
    with pytest.raises(ValueError, match=r"out: .*C-contiguous"):
        kern.jacobian_data(u, out=np.zeros(2 * out.size)[::2])
    with pytest.raises(ValueError, match=rf"u: shape \(3,\), expected \({kern.nu},\)"):
        kern.jacobian_data(u[:3])
    with pytest.raises(ValueError, match=rf"b: shape \(4,\), expected \({kern.nu},\)"):
        kern.apply(u, u[:4])
    with pytest.raises(ValueError, match=r"maps: shape \(2, 5\), expected \(24, 5\)"):
        ConvectionKernel(kern.edofs, np.zeros((2, 5)),
                         (np.zeros((6, 3)), np.zeros((6, 2, 3)), np.ones(3)))
    with pytest.raises(ValueError, match=r"reference\[1\] \(dref\): shape \(6, 3\)"):
        ConvectionKernel(kern.edofs, np.zeros((24, 5)),
                         (np.zeros((6, 3)), np.zeros((6, 3)), np.ones(3)))


@pytest.mark.parametrize("convection", [False, True])
@pytest.mark.parametrize("ale", [False, True])
def test_operator_jacobian_action_equals_the_assembled_jacobian(convection, ale):
    """The matrix-free Jacobian that Newton-Krylov applies equals the assembled one
    (``NavierStokesOperator.jacobian``, a refresh's matrix) on the free DOFs, with and
    without convection and mesh velocity, to round-off."""
    from skfem_granular.fluid.boundary import DirichletData
    from skfem_granular.fluid.operator import NavierStokesOperator

    space = sg.TaylorHood(_mesh(2))
    op = NavierStokesOperator(space, sg.Fluid(1000.0, 1e-3), DirichletData(space, {"all": (0, 0)}),
                              convection=convection)
    rng = np.random.default_rng(7)
    x = rng.standard_normal(space.N)
    w = rng.standard_normal(space.nu) if ale else None
    a0 = 1.5 / 1e-3
    J = op.jacobian(x, a0, w_mesh=w)
    for _ in range(3):
        dx = np.zeros(space.N)
        dx[op.free] = rng.standard_normal(op.free.size)
        Jdx = op.jacobian_action(x, dx, op.velocity_block(a0), w)
        assert np.abs(Jdx - J @ dx)[op.free].max() <= 1e-12 * np.abs(J @ dx).max()
