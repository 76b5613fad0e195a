"""Linear solvers agree, bad input is refused clearly, mirror symmetry holds to round-off.

References: validation case 1 (concentric-cylinder drag) for the solver
comparison, case 8 (symmetry) for the mirrored mesh.
"""

import warnings

import numpy as np
import pytest
import triangle
from helpers import annulus, box, coupled_run_through, regular_polygon
from scipy.spatial import cKDTree
from skfem import MeshQuad, MeshTri

import skfem_granular as sg
from skfem_granular.fluid import linsolve
from skfem_granular.fluid.linsolve import (
    AUTO_KRYLOV_SIZE,
    KrylovSolver,
    SuperLUSolver,
    make_solver,
)

EPS = np.finfo(float).eps


def drag_concentric(a, b, mu, U):
    """validation case 1: F = -4 pi mu U / (ln(b/a) - (b^2 - a^2)/(b^2 + a^2))."""
    return -4 * np.pi * mu * U / (np.log(b / a) - (b**2 - a**2) / (b**2 + a**2))


# linear solvers ----------------------------------------------------------------------


@pytest.fixture(scope="module")
def drag_solves():
    """The annulus drag case (a = 1, b = 2, 64/128 segments, ~10k unknowns) with both solvers."""
    space = sg.TaylorHood(annulus(1.0, 2.0, 64, 128, 25.0 / 64**2))
    fluid = sg.Fluid(1.0, 1.0)
    bc = {"inner": (1.0, 0.0), "outer": (0.0, 0.0)}
    return {name: sg.solve_steady(space, fluid, bc, solver=name) for name in ("superlu", "krylov")}


def test_superlu_and_krylov_give_the_same_stokes_solution(drag_solves):
    lu, kr = drag_solves["superlu"], drag_solves["krylov"]
    assert kr.space.N > 10_000
    # FGMRES stops at 1e-10 relative residual; measured differences 2.7e-11 (u), 5.0e-11 (p)
    assert np.linalg.norm(kr.u - lu.u) < 1e-8 * np.linalg.norm(lu.u)
    assert np.linalg.norm(kr.p - lu.p) < 1e-8 * np.linalg.norm(lu.p)
    F = drag_concentric(1.0, 2.0, 1.0, 1.0)
    for method in ("consistent", "traction"):
        f_lu, f_kr = lu.force("inner", method), kr.force("inner", method)
        assert abs(f_kr[0] - f_lu[0]) < 1e-8 * abs(F)
        assert abs(f_lu[0] / F - 1) < 5e-3  # the discretisation error dwarfs the solver's
    # statistics: SuperLU has no Krylov iterations, FGMRES one count per solve
    assert lu.report.solver["name"] == "superlu"
    assert lu.report.solver["krylov_iterations"] == []
    its = kr.report.solver["krylov_iterations"]
    assert kr.report.solver["name"] == "krylov" and len(its) == 1
    # measured 36 (one V-cycle and a lumped pressure mass needed 208)
    assert 0 < its[0] <= 60
    assert kr.report.residuals[0] < 1e-9


def test_krylov_steady_navier_stokes_re100_matches_superlu():
    """Newton Jacobians are non-symmetric: ILU velocity block and least-squares commutator.

    Annulus drag case at Re = rho U a / mu = 100 (32/64 segments). With the
    Cahouet-Chabard Schur approximation FGMRES stalled at relative residual
    ~1 (Re = 100) and 2e-6 (Re = 33) after 300 iterations.
    """
    mesh = annulus(1.0, 2.0, 32, 64, 25.0 / 32**2)
    fluid = sg.Fluid(1.0, 0.01)
    bc = {"inner": (1.0, 0.0), "outer": (0.0, 0.0)}
    lu = sg.solve_steady(mesh, fluid, bc, convection=True, solver="superlu")
    kr = sg.solve_steady(mesh, fluid, bc, convection=True, solver="krylov")
    assert kr.report.iterations == lu.report.iterations  # same Newton history
    assert np.linalg.norm(kr.x - lu.x) < 1e-8 * np.linalg.norm(lu.x)  # measured 4e-16
    its = kr.report.solver["krylov_iterations"]
    assert len(its) == kr.report.iterations and max(its) <= 100  # measured 34-67


def test_krylov_unsteady_stokes_matches_superlu():
    """BDF2 steps use the Cahouet-Chabard Schur approximation (a0 rho Lp^-1 term)."""
    mesh = annulus(1.0, 2.0, 16, 32, 0.02)
    bc = {"inner": (1.0, 0.0), "outer": (0.0, 0.0)}
    out = {}
    for solver in ("superlu", "krylov"):
        *_, (t, flow) = sg.evolve(mesh, sg.Fluid(1.0, 0.1), bc, dt=0.05, t_end=0.15,
                                  convection=False, solver=solver)
        out[solver] = flow
    assert t == pytest.approx(0.15)
    lu, kr = out["superlu"], out["krylov"]
    assert np.linalg.norm(kr.u - lu.u) < 1e-8 * np.linalg.norm(lu.u)
    assert np.linalg.norm(kr.x - lu.x) < 1e-8 * np.linalg.norm(lu.x)


@pytest.mark.parametrize("dt", [1e-5, 1e-3])
def test_krylov_without_viscosity_uses_the_commutator(dt):
    """A caller that passes only ``Mp`` (as a coupled rigid-body system does).

    BDF2-Stokes matrix ``[[a0 rho M + eta K, B^T], [B, 0]]`` for water in a
    2 mm annulus; Cahouet-Chabard with a guessed eta = 1 did not converge
    in 300 iterations, the least-squares commutator needs 7-14.
    """
    from scipy.sparse.linalg import spsolve

    from skfem_granular.fluid.boundary import DirichletData
    from skfem_granular.fluid.operator import NavierStokesOperator

    space = sg.TaylorHood(annulus(1e-3, 2e-3, 32, 64, (8e-5) ** 2))
    bc = {"inner": (0.0, 1e-3), "outer": (0.0, 0.0)}
    op = NavierStokesOperator(space, sg.Fluid(1000.0, 1e-3), DirichletData(space, bc))
    a0 = 1.5 / dt
    J = op.reduced(op.matrix(op.velocity_block(a0)))
    b = -op.residual(op.apply_dirichlet(np.zeros(space.N)), c_mass=a0)[op.free]
    kr = KrylovSolver()
    kr.factorize(J, op.nu_free, Mp=op.solver_blocks(a0)["Mp"])
    x = kr.solve(b)
    ref = spsolve(J.tocsc(), b)
    assert np.linalg.norm(x - ref) < 1e-8 * np.linalg.norm(ref)
    assert kr.stats.iterations[0] <= 30  # measured 7 (dt 1e-5), 14 (dt 1e-3)


def test_krylov_on_a_system_smaller_than_maxiter():
    """pyamg warns when maxiter exceeds the system size (and forces its warnings to 'always')."""
    mesh = annulus(1.0, 2.0, 6, 8, 1.0)
    bc = {"inner": (0.0, 1.0), "outer": (0.0, 0.0)}
    lu = sg.solve_steady(mesh, sg.Fluid(1.0, 1.0), bc, solver="superlu")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        kr = sg.solve_steady(mesh, sg.Fluid(1.0, 1.0), bc, solver="krylov")
    assert [str(w.message) for w in caught] == []
    assert lu.space.N < KrylovSolver().maxiter
    np.testing.assert_allclose(kr.x, lu.x, rtol=0, atol=1e-8 * np.abs(lu.x).max())


def test_krylov_iteration_limit_raises(drag_solves):
    space = drag_solves["krylov"].space
    bc = {"inner": (1.0, 0.0), "outer": (0.0, 0.0)}
    with pytest.raises(sg.ConvergenceError, match="after 3 iterations"):
        sg.solve_steady(space, sg.Fluid(1.0, 1.0), bc, solver=KrylovSolver(maxiter=3))


def test_make_solver_choices(monkeypatch):
    monkeypatch.setattr(linsolve, "_PARDISO_AVAILABLE", False)  # as without pypardiso
    assert make_solver("auto", 1000).name == "superlu"
    assert make_solver("auto", AUTO_KRYLOV_SIZE).name == "superlu"
    assert make_solver("auto", AUTO_KRYLOV_SIZE + 1).name == "krylov"
    assert make_solver("krylov").name == "krylov"
    own = SuperLUSolver(delta=0.0)
    assert make_solver(own) is own
    for bad in ("nope", "SuperLU", 3, None, ["krylov"]):
        with pytest.raises(ValueError, match="'auto', 'superlu', 'pardiso', 'krylov'"):
            make_solver(bad)
    with pytest.raises(ValueError, match="solver = 'nope'"):
        sg.solve_steady(annulus(1.0, 2.0, 6, 8, 1.0), sg.Fluid(), {"inner": (0, 0)}, solver="nope")
    for kw in (dict(rtol=-1.0), dict(rtol=float("nan")), dict(maxiter=0), dict(restart=0)):
        with pytest.raises(ValueError):
            KrylovSolver(**kw)


def test_pardiso_is_optional():
    try:
        import pypardiso  # noqa: F401
    except ImportError:
        with pytest.raises(ValueError, match="pypardiso"):
            make_solver("pardiso")
    else:
        mesh = annulus(1.0, 2.0, 16, 32, 0.02)
        bc = {"inner": (1.0, 0.0), "outer": (0.0, 0.0)}
        a = sg.solve_steady(mesh, sg.Fluid(), bc, solver="superlu")
        b = sg.solve_steady(mesh, sg.Fluid(), bc, solver="pardiso")
        assert np.linalg.norm(a.x - b.x) < 1e-10 * np.linalg.norm(a.x)
        # Newton: PARDISO analyses one pattern (the Stokes matrix of the first step and the
        # Jacobians share it: the velocity blocks come on the convection's element pattern,
        # cross-component couplings included) and refactorises numerically after
        pds = make_solver("pardiso")
        c = sg.solve_steady(mesh, sg.Fluid(1.0, 0.05), bc, True, solver=pds)
        d = sg.solve_steady(mesh, sg.Fluid(1.0, 0.05), bc, True, solver="superlu")
        assert c.report.iterations >= 3
        assert pds.analyses_reused == pds.stats.factorizations - 1
        assert np.linalg.norm(c.x - d.x) < 1e-9 * np.linalg.norm(d.x)


# bad input ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def small():
    mesh = annulus(1.0, 2.0, 8, 16, 0.2)
    flow = sg.solve_steady(mesh, sg.Fluid(), {"inner": (1.0, 0.0), "outer": (0.0, 0.0)})
    return mesh, flow


def test_unknown_boundary_lists_the_available_names(small):
    mesh, flow = small
    with pytest.raises(ValueError, match=r"velocity\['wall'\]: no such boundary.*'outer', 'inner'"):
        sg.solve_steady(mesh, sg.Fluid(), {"inner": (1, 0), "wall": (0, 0)})
    with pytest.raises(ValueError, match=r"boundary\['particle0'\].*'outer', 'inner'"):
        flow.force("particle0")
    with pytest.raises(ValueError, match="must be a mapping"):
        sg.solve_steady(mesh, sg.Fluid(), [("inner", (1, 0))])


@pytest.mark.parametrize("spec, match", [
    ((np.nan, 0.0), "must be 2 finite numbers"),
    ((1.0, np.inf), "must be 2 finite numbers"),
    ((1.0, 2.0, 3.0), "must be 2 finite numbers"),
    ("fast", "must be 2 finite numbers"),
    (None, "must be 2 finite numbers"),
    (lambda x, y: (np.log(x - x), y), "NaN or inf"),
    (lambda x, y: (x, y, x), "must return two components"),
    (lambda x, y: 1.0, "must return two components"),
    (lambda x, y: (x[:2], y), "array of 32 values"),
    (lambda x, y: 1 / 0, "raised ZeroDivisionError"),
])
def test_bad_boundary_values(small, spec, match):
    mesh, _ = small
    with np.errstate(divide="ignore"), pytest.raises(ValueError, match=r"^velocity\['inner'\]"):
        sg.solve_steady(mesh, sg.Fluid(), {"inner": spec, "outer": (0, 0)})
    with np.errstate(divide="ignore"), pytest.raises(ValueError, match=match):
        sg.solve_steady(mesh, sg.Fluid(), {"inner": spec, "outer": (0, 0)})


def test_closed_domain_with_net_flux_is_refused():
    """Div u = 0 needs zero net flux when every boundary has velocity data.

    Inflow u = y (1 - y) through the left side of [0, 3] x [0, 1] carries 1/6
    per unit depth; with the outlet closed the data are impossible.
    """
    mesh = box(0.0, 0.0, 3.0, 1.0, 0.05)

    def profile(x, y):
        return y * (1 - y), 0 * y

    walls = {"top": (0, 0), "bottom": (0, 0)}
    msg = r"net outflow of -0.166667 per unit depth \(100.0% of the total"
    with pytest.raises(ValueError, match=msg):
        sg.solve_steady(mesh, sg.Fluid(), {"left": profile, "right": (0, 0), **walls})
    # balanced (the same profile leaves on the right) or open outlet: accepted
    for bc in ({"left": profile, "right": profile, **walls}, {"left": profile, **walls}):
        flow = sg.solve_steady(mesh, sg.Fluid(), bc)
        pts = np.array([[1.5, 2.0], [0.3, 0.8]])
        np.testing.assert_allclose(flow.velocity(pts), profile(*pts), atol=1e-12)
    # rigid motions of the walls carry no flux
    ring = annulus(1.0, 2.0, 16, 32, 0.05)
    sg.solve_steady(ring, sg.Fluid(), {"inner": sg.RigidMotion((1.0, 2.0), 3.0, (0.1, 0.2)),
                                       "outer": sg.RigidMotion((0.0, 1.0), -1.0)})

    def growing(x, y, t):  # a translation, plus a radial source switched on at t = 0.1
        s = max(t - 0.1, 0.0)
        return 1.0 + s * x, s * y

    with pytest.raises(ValueError, match=r"the data at t = 0\.1\d* carry a net outflow"):
        for _ in sg.evolve(ring, sg.Fluid(), {"inner": growing, "outer": (0, 0)}, dt=0.05,
                           t_end=0.3, convection=False):
            pass


def test_bad_body_force_is_named(small):
    mesh, _ = small
    with pytest.raises(ValueError, match=r"^body_force"):
        sg.solve_steady(mesh, sg.Fluid(), {"inner": (0, 0)}, body_force=(np.nan, 0.0))


@pytest.mark.parametrize("kw, match", [
    (dict(density=0.0), "Fluid.density = 0.0"),
    (dict(density=-1000.0), "Fluid.density = -1000.0"),
    (dict(density=np.inf), "Fluid.density = inf"),
    (dict(viscosity=np.nan), "Fluid.viscosity = nan"),
    (dict(viscosity=0.0), "Fluid.viscosity = 0.0"),
    (dict(viscosity="water"), "Fluid.viscosity = 'water'"),
    (dict(viscosity=None), "Fluid.viscosity = None"),
])
def test_bad_fluid(kw, match):
    with pytest.raises(ValueError, match=match):
        sg.Fluid(**kw)


@pytest.mark.parametrize("mesh", [np.zeros((2, 3)), None, "mesh.msh", MeshQuad()],
                         ids=["array", "None", "str", "MeshQuad"])
def test_non_mesh_is_refused_by_every_entry_point(mesh):
    bc = {"inner": (0.0, 0.0)}
    with pytest.raises(ValueError, match="mesh: a skfem.MeshTri is required"):
        sg.TaylorHood(mesh)
    with pytest.raises(ValueError, match="mesh: a skfem.MeshTri is required"):
        sg.solve_steady(mesh, sg.Fluid(), bc)
    with pytest.raises(ValueError, match="mesh: a skfem.MeshTri is required"):
        sg.BDF2Integrator(mesh, sg.Fluid(), bc)
    with pytest.raises(ValueError, match="mesh: a skfem.MeshTri is required"):
        next(sg.evolve(mesh, sg.Fluid(), bc, dt=0.1, t_end=1.0))


def test_non_fluid_is_refused(small):
    mesh, _ = small
    with pytest.raises(ValueError, match="fluid: a skfem_granular.Fluid is required, got tuple"):
        sg.solve_steady(mesh, (1000.0, 1e-3), {"inner": (0, 0)})


@pytest.mark.parametrize("method", ["stress", "Traction", None, ""])
def test_bad_force_method(small, method):
    _, flow = small
    with pytest.raises(ValueError, match="must be 'consistent' or 'traction'"):
        flow.force("inner", method=method)
    with pytest.raises(ValueError, match="must be 'consistent' or 'traction'"):
        flow.torque("inner", method=method)


def test_bad_torque_center(small):
    _, flow = small
    for center in ((np.nan, 0.0), (0.0, 0.0, 0.0), "origin"):
        with pytest.raises(ValueError, match="center"):
            flow.torque("inner", center=center)


@pytest.mark.parametrize("kw, match", [
    (dict(velocity=(1.0, 2.0, 3.0)), "RigidMotion.velocity"),
    (dict(velocity=(np.nan, 0.0)), "RigidMotion.velocity"),
    (dict(velocity="up"), "RigidMotion.velocity"),
    (dict(center=(0.0,)), "RigidMotion.center"),
    (dict(center=(0.0, np.inf)), "RigidMotion.center"),
    (dict(omega=np.nan), "RigidMotion.omega = nan"),
    (dict(omega=None), "RigidMotion.omega = None"),
    (dict(omega="fast"), "RigidMotion.omega = 'fast'"),
    (dict(omega=[1.0, 2.0]), r"RigidMotion.omega = \[1.0, 2.0\]"),
])
def test_malformed_rigid_motion(kw, match):
    with pytest.raises(ValueError, match=match):
        sg.RigidMotion(**kw)


def test_rigid_motion_values():
    """u = V + omega e_z x (x - X), stored as plain floats."""
    m = sg.RigidMotion(velocity=np.array([1.0, -2.0]), omega=np.float32(0.5), center=(1.0, 1.0))
    assert m.omega == 0.5 and type(m.omega) is float
    ux, uy = m(np.array([3.0]), np.array([5.0]))
    assert (ux[0], uy[0]) == (1.0 - 0.5 * 4.0, -2.0 + 0.5 * 2.0)


def test_bad_tolerance_for_point_values(small):
    _, flow = small
    for tol in (-1.0, np.nan):
        with pytest.raises(ValueError, match="tol"):
            flow.velocity([[1.5], [0.0]], tol=tol)


# symmetry (validation case 8) -----------------------------------------------------


def half_box_with_hole(W, H, r, n, max_area):
    """Right half (x >= 0) of [-W, W] x [-H, H] minus a regular 2n-gon of radius r at the origin."""
    phi = np.pi / 2 - np.pi * np.arange(n + 1) / n  # from (0, r) clockwise to (0, -r)
    arc = np.array([r * np.cos(phi), r * np.sin(phi)])
    arc[0, [0, -1]] = 0.0
    V = np.vstack([[[0.0, -H], [W, -H], [W, H], [0.0, H]], arc.T])
    k = V.shape[0]
    S = np.stack([np.arange(k), (np.arange(k) + 1) % k], axis=1)
    out = triangle.triangulate(dict(vertices=V, segments=S), f"pq30a{max_area:.12f}")
    return MeshTri(out["vertices"].T.copy(), out["triangles"].T.copy())


def mirrored_box(W=1.0, H=2.0, r=0.3, n=24, max_area=0.01):
    """Box with a 2n-gon hole, mirror-symmetric mesh: a half mesh and its mirror image."""
    half = half_box_with_hole(W, H, r, n, max_area)
    mesh = half + half.mirrored((1.0, 0.0))
    bf = mesh.boundary_facets()
    mid = mesh.p[:, mesh.facets[:, bf]].mean(axis=1)
    outer = np.isclose(np.abs(mid[0]), W) | np.isclose(np.abs(mid[1]), H)
    return mesh.with_boundaries({"wall": bf[outer], "particle0": bf[~outer]})


@pytest.mark.parametrize("convection, mu", [(False, 1.0), (True, 0.05)],
                         ids=["stokes", "navier-stokes-Re12"])
def test_vertical_motion_on_mirror_symmetric_mesh_has_no_horizontal_force(convection, mu):
    """Box [-1, 1] x [-2, 2], 48-gon of radius 0.3 at the centre moving up, closed walls.

    Mirror-symmetric mesh (1354 triangles): the horizontal force and the
    asymmetry of the velocity measure rounding error alone. The same
    problem on an ordinary (unsymmetric) triangle mesh shows the
    discretisation error instead.
    """
    mesh = mirrored_box()
    P = mesh.p
    dist, _ = cKDTree(P.T).query((P * [[-1.0], [1.0]]).T)
    assert dist.max() == 0.0  # the vertex set is its own mirror image
    bc = {"wall": (0.0, 0.0), "particle0": (0.0, 1.0)}
    flow = sg.solve_steady(mesh, sg.Fluid(1.0, mu), bc, convection=convection)
    for method in ("traction", "consistent"):
        F = flow.force("particle0", method)
        assert abs(F[0]) < 1e2 * EPS * abs(F[1])  # measured 7.7e-15 / 4.3e-16 relative
        # torque about the centre, relative to the force times the radius
        assert abs(flow.torque("particle0", (0, 0), method)) < 1e2 * EPS * abs(F[1]) * 0.3
    # u_x is odd, u_y even under x -> -x; u_x = 0 on the symmetry line
    loc = flow.space.sb.doflocs
    d, j = cKDTree(loc.T).query((loc * [[-1.0], [1.0]]).T)
    assert d.max() < 1e2 * EPS
    ux, uy = flow.u[0::2], flow.u[1::2]
    # SuperLU's refinement stops at 1e-13 relative residual; measured 1.1e-11 (Stokes)
    assert np.abs(ux + ux[j]).max() < 1e-10
    assert np.abs(uy - uy[j]).max() < 1e-10
    assert np.abs(ux[np.abs(loc[0]) < 1e-14]).max() < 1e-10

    unsym = sg.solve_steady(box(-1.0, -2.0, 1.0, 2.0, 0.01,
                                hole=regular_polygon(48, 0.3, angle=np.pi / 2)),
                            sg.Fluid(1.0, mu), bc, convection=convection)
    Fu = unsym.force("particle0")
    # discretisation error: measured 1.1e-6 (Stokes), 1.7e-5 (Navier-Stokes) relative
    assert abs(Fu[0]) < 1e-4 * abs(Fu[1])
    assert Fu[1] == pytest.approx(F[1], rel=1e-3)


def test_krylov_corrections_to_a_looser_tolerance():
    """Newton corrections need not be solved to rtol (the loop evaluates the exact
    residual): to ``correction_rtol`` (default 1e-4) the Re 100 annulus takes fewer
    FGMRES iterations and the same Newton iterations, and lands on the same flow."""
    mesh = annulus(1.0, 2.0, 32, 64, 25.0 / 32**2)
    fluid = sg.Fluid(1.0, 0.01)
    bc = {"inner": (1.0, 0.0), "outer": (0.0, 0.0)}
    tight = sg.solve_steady(mesh, fluid, bc, convection=True,
                            solver=KrylovSolver(correction_rtol=1e-10))
    loose = sg.solve_steady(mesh, fluid, bc, convection=True, solver="krylov")
    assert KrylovSolver().correction_rtol == linsolve.CORRECTION_RTOL == 1e-4
    assert loose.report.iterations <= tight.report.iterations + 1
    assert np.linalg.norm(loose.x - tight.x) < 1e-8 * np.linalg.norm(tight.x)
    n_tight = sum(tight.report.solver["krylov_iterations"])
    n_loose = sum(loose.report.solver["krylov_iterations"])
    assert n_loose < 0.7 * n_tight, (n_loose, n_tight)
    with pytest.raises(ValueError, match="correction_rtol"):
        KrylovSolver(correction_rtol=0.0)


def test_fallback_factorisation_that_would_not_fit_is_refused(monkeypatch):
    """Refinement that stalls (an inconsistent right-hand side of a singular system) falls
    back to threshold pivoting, whose factors are nearly dense; when they would not fit in
    the memory left, one FactorizationMemoryError names both sizes instead."""
    import scipy.sparse as sp

    from skfem_granular import memory
    from skfem_granular.fluid.linsolve import FactorizationMemoryError
    from skfem_granular.fluid.superlu import BYTES_PER_ENTRY, PIVOTED_ENTRIES_PER_SQUARED_UNKNOWN

    A = sp.csr_matrix(np.array([[2.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]))
    s = SuperLUSolver().factorize(A, 1)
    need = PIVOTED_ENTRIES_PER_SQUARED_UNKNOWN * BYTES_PER_ENTRY * 3**2
    monkeypatch.setattr(memory, "available", lambda: 0.5 * need)
    with pytest.raises(FactorizationMemoryError, match=r"on 3 unknowns iterative refinement "
                                                       r"stalled .* would need about .* GB left"):
        s.solve(np.array([1.0, 1.0, 1.0]))
    monkeypatch.setattr(memory, "available", lambda: 2.0 * need)  # fits: SuperLU tries it
    with pytest.raises(RuntimeError, match="singular"):
        s.solve(np.array([1.0, 1.0, 1.0]))


def test_a_coupled_run_on_the_krylov_path_matches_superlu(monkeypatch):
    """The monolithic coupled step through the Krylov solver (what ``"auto"`` picks from
    AUTO_KRYLOV_SIZE unknowns on, lowered here to 0): the paper's particle over 20 steps
    follows the SuperLU run to the solvers' tolerance (measured 5e-13 in v_y)."""
    h, ref, solver = coupled_run_through(monkeypatch, "AUTO_KRYLOV_SIZE")
    assert solver == "krylov"
    np.testing.assert_allclose(h.vy, ref.vy, rtol=1e-9, atol=1e-9 * np.abs(ref.vy).max())
    np.testing.assert_allclose(h.y, ref.y, rtol=1e-12)
