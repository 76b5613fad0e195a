"""User terms (scikit-fem forms) in the fluid solves, checked against analytic solutions.

- Brinkman drag ``alpha u . v`` in a steady channel: the Poiseuille-Brinkman profile
  ``U(y) = (G / alpha) (1 - cosh(k (y - h/2)) / cosh(k h/2))``, ``k = sqrt(alpha / mu)``;
  the P2 velocity converges at order 3 in L2 and 2 in H1.
- A space- and time-dependent body force (a ``LinearForm``) manufacturing
  ``u = g(t) (x^2, -2 x y)``, ``p = g(t) (x + y - 1)`` for the unsteady Navier-Stokes
  equations; P2/P1 hold that solution exactly, so the error left is BDF2's: order 2.
- A mass source ``div u = 2 x`` through continuity forms (a LinearForm, and a
  BilinearForm doubling the built-in divergence): a P2/P1 solution to round-off.
"""

from collections import deque

import numpy as np
import pytest
from skfem import BilinearForm, Functional, LinearForm, MeshTri
from skfem.helpers import dot

import skfem_granular as sg
from skfem_granular.fluid import UserTerms, evolve, solve_steady


def channel(n: int, length: float = 1.0, height: float = 1.0) -> MeshTri:
    """Structured ``n x n`` channel ``[0, length] x [0, height]``, named boundaries."""
    m = MeshTri.init_tensor(np.linspace(0, length, n + 1), np.linspace(0, height, n + 1))
    return m.with_boundaries({"left": lambda x: np.isclose(x[0], 0.0),
                              "right": lambda x: np.isclose(x[0], length),
                              "bottom": lambda x: np.isclose(x[1], 0.0),
                              "top": lambda x: np.isclose(x[1], height)})


def rate(hs, errors) -> float:
    """Least-squares slope of log(error) against log(h)."""
    return float(np.polyfit(np.log(hs), np.log(errors), 1)[0])


# ---------------------------------------------------------------- Brinkman channel
MU, ALPHA, G, H = 1.0, 100.0, 100.0, 1.0
K = np.sqrt(ALPHA / MU)


def brinkman_profile(y):
    """``U(y)`` of plane Poiseuille-Brinkman flow, and ``U'(y)``."""
    c = np.cosh(K * H / 2)
    return (G / ALPHA) * (1 - np.cosh(K * (y - H / 2)) / c), -(G / ALPHA) * K * np.sinh(
        K * (y - H / 2)) / c


@BilinearForm
def brinkman_drag(u, v, w):
    return ALPHA * dot(u, v)


@Functional
def error_l2(w):
    U = brinkman_profile(w.x[1])[0]
    return (w["u"][0] - U) ** 2 + w["u"][1] ** 2


@Functional
def error_h1(w):
    dU = brinkman_profile(w.x[1])[1]
    g = w["u"].grad
    return g[0, 0] ** 2 + (g[0, 1] - dU) ** 2 + g[1, 0] ** 2 + g[1, 1] ** 2


def brinkman_errors(n: int) -> tuple[float, float]:
    mesh = channel(n, height=H)
    inflow = lambda x, y: (brinkman_profile(y)[0], 0.0 * y)  # noqa: E731
    flow = solve_steady(mesh, sg.Fluid(1.0, MU), {"left": inflow, "bottom": (0, 0),
                                                  "top": (0, 0)},
                        terms=UserTerms(momentum=[brinkman_drag]))  # right: do-nothing
    ub = flow.space.ub
    uh = ub.interpolate(flow.u)
    return (float(np.sqrt(error_l2.assemble(ub, u=uh))),
            float(np.sqrt(error_h1.assemble(ub, u=uh))))


def test_brinkman_channel_converges_at_p2_order():
    """Steady channel with a Brinkman drag term: L2 error ~ h^3, H1 error ~ h^2."""
    ns = [4, 8, 16, 32]
    errs = np.array([brinkman_errors(n) for n in ns])
    hs = 1.0 / np.array(ns)
    umax = G / ALPHA * (1 - 1 / np.cosh(K * H / 2))
    # measured (n = 8, 16, 32): L2 rate 2.93 (local 2.89, 2.97), H1 rate 1.93; finest L2
    # error 5.1e-5 (the profile's maximum is 0.987)
    assert rate(hs[1:], errs[1:, 0]) > 2.7
    assert rate(hs[1:], errs[1:, 1]) > 1.85
    assert errs[-1, 0] < 1e-4 * umax
    # without the term the flow is far from that profile: the term is in the equations
    plain = solve_steady(channel(8), sg.Fluid(1.0, MU),
                         {"left": lambda x, y: (brinkman_profile(y)[0], 0 * y),
                          "bottom": (0, 0), "top": (0, 0)})
    uh = plain.space.ub.interpolate(plain.u)
    assert np.sqrt(error_l2.assemble(plain.space.ub, u=uh)) > 20 * errs[1, 0]  # 42x


# -------------------------------------------------- manufactured unsteady Navier-Stokes
RHO, NU_VISC = 1.0, 0.1


def g(t):
    return 1.0 + 0.5 * np.sin(t)


def dg(t):
    return 0.5 * np.cos(t)


@LinearForm
def manufactured_force(v, w):
    """``rho u_t + rho (u . grad) u - mu lap u + grad p`` for the exact solution."""
    x, y = w.x
    t = w["t"]
    fx = RHO * dg(t) * x**2 + RHO * g(t) ** 2 * 2 * x**3 - NU_VISC * g(t) * 2 + g(t)
    fy = RHO * dg(t) * (-2 * x * y) + RHO * g(t) ** 2 * 2 * x**2 * y + g(t)
    return fx * v[0] + fy * v[1]


def exact_velocity(x, y, t=0.0):
    return g(t) * x**2, -2.0 * g(t) * x * y


def time_error(dt: float, t_end: float = 1.0) -> tuple[float, float]:
    mesh = MeshTri.init_tensor(np.linspace(0, 1, 5), np.linspace(0, 1, 5)).with_boundaries(
        {"wall": lambda x: np.ones(x.shape[1], dtype=bool)})
    (t, flow), = deque(evolve(mesh, sg.Fluid(RHO, NU_VISC), {"wall": exact_velocity}, dt=dt,
                              t_end=t_end, u0=exact_velocity, newton_tol=1e-13,
                              terms=UserTerms(momentum=manufactured_force)), maxlen=1)
    loc = flow.space.velocity_doflocs
    ux, uy = exact_velocity(loc[0], loc[1], t)
    exact = np.where(flow.space.component == 0, ux, uy)
    p_exact = g(t) * (flow.space.pb.doflocs.sum(axis=0) - 1.0)
    return float(np.abs(flow.u - exact).max()), float(np.abs(flow.p - p_exact).max())


def test_manufactured_body_force_bdf2_order_two():
    """A LinearForm body force f(x, t) through fluid.evolve: BDF2 order 2 in time."""
    dts = np.array([0.1, 0.05, 0.025, 0.0125])
    errs = np.array([time_error(dt) for dt in dts])
    # measured: velocity error 4.9e-5, 1.2e-5, 2.9e-6, 7.1e-7 (rate 2.03), pressure rate 2.04
    assert rate(dts, errs[:, 0]) > 1.8
    assert rate(dts, errs[:, 1]) > 1.8
    assert errs[-1, 0] < 1e-3 * g(1.0)


# ---------------------------------------------------------------------- bad input
def test_user_terms_bad_input():
    with pytest.raises(ValueError, match=r"UserTerms.momentum\[0\]: must be a skfem"):
        UserTerms(momentum=[lambda u, v, w: dot(u, v)])
    with pytest.raises(ValueError, match=r"UserTerms.continuity: must be"):
        UserTerms(continuity=3.0)
    # a scalar form among the momentum terms: not one value per quadrature point
    with pytest.raises(ValueError, match=r"UserTerms.momentum\[0\]: .*velocity \(P2 vector\)"):
        UserTerms(momentum=[BilinearForm(lambda u, v, w: u * v)])
    with pytest.raises(ValueError, match=r"UserTerms.continuity\[0\]: .*pressure \(P1\)"):
        UserTerms(continuity=[LinearForm(lambda q, w: dot(q, q))])
    with pytest.raises(ValueError, match="terms: a skfem_granular.fluid.UserTerms"):
        solve_steady(channel(2), sg.Fluid(1.0, 1.0), {"left": (1, 0)}, terms=[brinkman_drag])


# ------------------------------------------------------------------ continuity terms
def test_mass_source_and_continuity_bilinear_form_exact():
    """``div u = s`` through continuity forms in a channel with a do-nothing outlet:
    ``u = (x^2, 0)`` (``s = 2 x``) and ``p = x - 1 + 2 mu`` (the outlet's
    ``mu du/dn - p n = 0`` at ``x = 1``) lie in P2/P1, so the solve reproduces them to
    round-off. The source alone (``g(q) = -(s, q)``), and the built-in ``-(q, div u)``
    doubled by a user BilinearForm with the source doubled (the same equation), give that
    solution. Momentum (Laplacian form): ``-mu lap u + grad p = (1 - 2 mu, 0)``, a
    LinearForm too."""
    from skfem.helpers import div

    mu = 0.25
    force = LinearForm(lambda v, w: (1 - 2 * mu) * v[0])
    source = LinearForm(lambda q, w: -2.0 * w.x[0] * q)
    double_source = LinearForm(lambda q, w: -4.0 * w.x[0] * q)
    divergence = BilinearForm(lambda u, q, w: -div(u) * q)
    exact_u = lambda x, y: (x**2, 0 * y)  # noqa: E731
    for continuity in ([source], [divergence, double_source]):
        flow = solve_steady(channel(4), sg.Fluid(1.0, mu),
                            {"left": exact_u, "bottom": exact_u, "top": exact_u},
                            terms=UserTerms(momentum=force, continuity=continuity))
        loc = flow.space.velocity_doflocs
        exact = np.where(flow.space.component == 0, loc[0] ** 2, 0.0)
        assert np.abs(flow.u - exact).max() < 1e-12
        p_exact = flow.space.pb.doflocs[0] - 1.0 + 2 * mu
        assert np.abs(flow.p - p_exact).max() < 1e-11
        assert flow.report.iterations == 2  # Newton: the first solve is exact
    # without the source the flow cannot be that one (measured: 1.39 off)
    flow = solve_steady(channel(4), sg.Fluid(1.0, mu),
                        {"left": exact_u, "bottom": exact_u, "top": exact_u},
                        terms=UserTerms(momentum=force))
    assert np.abs(flow.u - exact).max() > 0.5


# ------------------------------------------------- the built-in viscous term, split
def test_user_viscous_term_on_a_moving_mesh_equals_the_compiled_one():
    """Taylor-Green flow, Navier-Stokes by BDF2 on a mesh whose interior oscillates (ALE):
    half the viscosity as a user BilinearForm (assembled on each moved mesh) gives the
    compiled run with the whole viscosity (measured 9e-16 relative)."""
    from skfem.helpers import ddot, sym_grad

    nu = 0.1
    mesh = MeshTri.init_tensor(np.linspace(0, np.pi, 7), np.linspace(0, np.pi, 7))
    mesh = mesh.with_boundaries({"wall": lambda x: np.ones(x.shape[1], dtype=bool)})
    p_ref = mesh.p
    phi = np.sin(p_ref[0]) * np.sin(p_ref[1])

    def motion(t):
        return p_ref + 0.1 * np.sin(2 * np.pi * t) * np.array([1.0, 0.6])[:, None] * phi

    def tg(x, y, t=0.0):
        d = np.exp(-2 * nu * t)
        return -np.cos(x) * np.sin(y) * d, np.sin(x) * np.cos(y) * d

    viscous = BilinearForm(lambda u, v, w: (nu / 2) * 2.0 * ddot(sym_grad(u), sym_grad(v)))
    runs = []
    for eta, terms in ((nu, None), (nu / 2, UserTerms(momentum=[viscous]))):
        (_, flow), = deque(evolve(mesh, sg.Fluid(1.0, eta), {"wall": tg}, dt=0.05, t_end=0.5,
                                  u0=tg, mesh_motion=motion, newton_tol=1e-12, terms=terms),
                           maxlen=1)
        runs.append(flow.u)
    assert np.abs(runs[1] - runs[0]).max() <= 1e-10 * np.abs(runs[0]).max()


# ------------------------------------------------- a coefficient that reads the flow
def test_convection_as_a_user_form_reading_the_velocity():
    """``((w["u"] . grad) u, v)`` as a user BilinearForm on a Stokes solve is the
    Navier-Stokes convection with its coefficient frozen at each iterate (Picard): past a
    square in a channel at Re 20 it converges to the compiled Navier-Stokes flow (measured
    1.6e-12 relative; 21 iterations against Newton's 6)."""
    from helpers import box
    from skfem.helpers import grad, mul

    hole = np.array([[0.4, 0.6, 0.6, 0.4], [0.4, 0.4, 0.6, 0.6]])
    mesh = box(0.0, 0.0, 2.0, 1.0, 0.01, hole=hole)
    bc = {"wall": (1.0, 0.0), "particle0": (0.0, 0.0)}
    convection = BilinearForm(lambda u, v, w: dot(mul(grad(u), w["u"]), v))
    newton = solve_steady(mesh, sg.Fluid(1.0, 0.01), bc, convection=True, tol=1e-12)
    picard = solve_steady(mesh, sg.Fluid(1.0, 0.01), bc, tol=1e-12, maxiter=80,
                          terms=UserTerms(momentum=[convection]))
    assert picard.report.iterations > newton.report.iterations  # linear convergence
    assert np.abs(picard.x - newton.x).max() <= 1e-10 * np.abs(newton.x).max()
