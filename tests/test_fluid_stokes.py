"""Steady Stokes against the analytic limits of docs/validation.md (cases 1-4)."""

import numpy as np
import pytest
from helpers import annulus, box, regular_polygon

import skfem_granular as sg

A, B, MU = 1.0, 2.0, 1.0


def drag_concentric(a, b, mu, U):
    """validation case 1: F = -4 pi mu U / (ln(b/a) - (b^2 - a^2)/(b^2 + a^2))."""
    return -4 * np.pi * mu * U / (np.log(b / a) - (b**2 - a**2) / (b**2 + a**2))


def torque_couette(a, b, mu, omega):
    """validation case 2: T = -4 pi mu Omega a^2 b^2 / (b^2 - a^2)."""
    return -4 * np.pi * mu * omega * a**2 * b**2 / (b**2 - a**2)


def faxen(k):
    """validation case 3: F/(mu U) for a cylinder on the centreline of a closed channel."""
    s = np.log(1 / k) - 0.9157 + 1.7244 * k**2 - 1.7302 * k**4 + 2.4056 * k**6 - 4.5913 * k**8
    return 4 * np.pi / s


def test_reference_numbers():
    assert drag_concentric(1, 2, 1, 1) == pytest.approx(-134.9088, abs=1e-4)
    assert faxen(1 / 3) == pytest.approx(35.3, abs=0.05)


@pytest.fixture(scope="module")
def annulus_levels():
    """Translation and rotation solves on three refinements (n segments on the inner circle)."""
    out = []
    for n in (32, 64, 128):
        mesh = annulus(A, B, n, 2 * n, 25.0 / n**2)
        space = sg.TaylorHood(mesh)
        fluid = sg.Fluid(1.0, MU)
        move = sg.solve_steady(space, fluid, {"inner": (1.0, 0.0), "outer": (0.0, 0.0)})
        spin = sg.solve_steady(space, fluid, {"inner": sg.RigidMotion(omega=1.0),
                                              "outer": (0.0, 0.0)})
        out.append((n, move, spin))
    return out


def _order(errors):
    e = np.asarray(errors)
    return np.log2(e[:-1] / e[1:])


def test_concentric_drag_both_methods_converge(annulus_levels):
    F = drag_concentric(A, B, MU, 1.0)
    err_c = [abs(m.force("inner")[0] / F - 1) for _, m, _ in annulus_levels]
    err_t = [abs(m.force("inner", method="traction")[0] / F - 1) for _, m, _ in annulus_levels]
    # finest mesh: within 1e-3 with both methods
    assert err_c[-1] < 1e-3
    assert err_t[-1] < 2e-3
    # observed orders (in the inner segment count): residual force ~2, traction >= 1.3
    assert np.all(_order(err_c) > 1.8)
    assert np.all(_order(err_t) > 1.3)
    # the consistent force is the more accurate one on every mesh
    assert all(c < t for c, t in zip(err_c, err_t, strict=True))
    # no lift on a symmetric geometry
    for _, m, _ in annulus_levels:
        assert abs(m.force("inner")[1]) < 1e-6 * abs(F)


def test_couette_torque_and_velocity(annulus_levels):
    T = torque_couette(A, B, MU, 1.0)
    err_c = [abs(s.torque("inner", center=(0, 0)) / T - 1) for _, _, s in annulus_levels]
    err_t = [abs(s.torque("inner", center=(0, 0), method="traction") / T - 1)
             for _, _, s in annulus_levels]
    # the residual torque is as accurate as the force; the traction integral
    # converges more slowly near the polygon's corners
    assert err_c[-1] < 1e-3
    assert np.all(_order(err_c) > 1.8)
    assert np.all(_order(err_t) > 1.0), err_t
    assert all(c < t for c, t in zip(err_c, err_t, strict=True))
    # velocity profile u_theta = Omega a^2 (b^2/r - r)/(b^2 - a^2) at r = 1.5
    _, _, spin = annulus_levels[-1]
    phi = np.linspace(0, 2 * np.pi, 7, endpoint=False)
    r = 1.5
    pts = np.array([r * np.cos(phi), r * np.sin(phi)])
    u = spin.velocity(pts)
    ut = -u[0] * np.sin(phi) + u[1] * np.cos(phi)
    exact = A**2 * (B**2 / r - r) / (B**2 - A**2)
    np.testing.assert_allclose(ut, exact, rtol=2e-3)


def test_plane_poiseuille_to_round_off():
    """validation case 4: u = G/(2 mu) y (H - y) is quadratic, P2 reproduces it."""
    H, L, mu, G = 1.0, 3.0, 0.01, 2.0
    mesh = box(0.0, 0.0, L, H, 0.02)

    def profile(x, y):
        return G / (2 * mu) * y * (H - y), 0.0 * y

    flow = sg.solve_steady(mesh, sg.Fluid(1.0, mu), {"left": profile, "bottom": (0, 0),
                                                     "top": (0, 0)})  # right: do-nothing
    loc = flow.space.velocity_doflocs
    ux, uy = profile(loc[0], loc[1])
    exact = np.where(flow.space.component == 0, ux, uy)
    umax = G * H**2 / (8 * mu)
    assert np.abs(flow.u - exact).max() < 1e-9 * umax
    # pressure gradient -G, and zero at the do-nothing outlet
    pts = np.array([[0.5, 1.5, 2.5], [0.5, 0.5, 0.5]])
    p = flow.pressure(pts)
    np.testing.assert_allclose(p, G * (L - pts[0]), rtol=1e-8, atol=1e-9 * G * L)
    # a Stokes solve never builds the convection kernel (0.7 s at 95k DOFs, unused)
    assert "convection" not in flow.space.__dict__


@pytest.mark.parametrize("k", [0.2, 1 / 3])
def test_faxen_closed_channel(k):
    """Cylinder moving along the centreline of a closed channel (half-gap l = 1)."""
    a = k
    hole = regular_polygon(160, a)
    mesh = box(-6.0, -1.0, 6.0, 1.0, 0.02, hole=hole)
    flow = sg.solve_steady(mesh, sg.Fluid(1.0, 1.0), {"wall": (0, 0), "particle0": (1.0, 0.0)})
    F = -flow.force("particle0")[0]
    assert F == pytest.approx(faxen(k), rel=3e-3)
    assert F == pytest.approx(-flow.force("particle0", method="traction")[0], rel=3e-3)


def test_symmetric_and_laplace_forms_agree_when_closed():
    """With Dirichlet data everywhere both viscous forms give the same drag.

    The discrete solutions differ by discretisation error only (Taylor-Hood
    velocities are weakly, not pointwise, divergence-free).
    """
    mesh = annulus(A, B, 64, 128, 25.0 / 64**2)
    fluid = sg.Fluid(1.0, MU)
    bc = {"inner": (1.0, 0.0), "outer": (0.0, 0.0)}
    F = drag_concentric(A, B, MU, 1.0)
    for viscous in ("symmetric", "laplace"):
        flow = sg.solve_steady(mesh, fluid, bc, viscous=viscous)
        assert flow.force("inner")[0] == pytest.approx(F, rel=2.5e-3)
