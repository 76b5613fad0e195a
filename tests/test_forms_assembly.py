"""``assembly="scikit-fem"``: the built-in blocks by ``asm`` of fluid/forms.py, against the
compiled kernels: the same blocks, the same solves, the paper's single particle to
round-off."""

from dataclasses import replace

import numpy as np
import pytest
from helpers import box

import skfem_granular as sg
from skfem_granular.scene import Scene
from skfem_granular.simulation import Simulation


def _moved(space, amplitude=0.05):
    p_ref = space.mesh.p
    phi = np.sin(np.pi * p_ref[0]) * np.sin(np.pi * p_ref[1])
    return space.moved(p_ref + amplitude * np.array([1.0, 0.6])[:, None] * phi)


def test_blocks_and_convection_equal_the_compiled_ones_on_moved_meshes():
    mesh = box(0.0, 0.0, 1.0, 1.0, 0.01)
    compiled, forms = sg.TaylorHood(mesh), sg.TaylorHood(mesh, assembly="scikit-fem")
    u = np.random.default_rng(2).standard_normal(compiled.nu)
    w = np.random.default_rng(3).standard_normal(compiled.nu)
    for a, b in ((compiled, forms), (_moved(compiled), _moved(forms))):
        assert b.assembly == "scikit-fem"
        for name in ("M", "K_symmetric", "K_laplace", "B", "Mp"):
            A, F = getattr(a, name), getattr(b, name)
            assert abs(A - F).max() <= 1e-13 * abs(A).max(), name
        for name in ("M", "K_laplace", "B"):  # on the compiled pattern (the solvers need it)
            assert np.array_equal(getattr(a, name).indptr, getattr(b, name).indptr)
            assert np.array_equal(getattr(a, name).indices, getattr(b, name).indices)
        ka, kb = a.convection, b.convection
        assert type(kb).__name__ == "FormsConvection"
        for va, vb in ((ka.residual(u), kb.residual(u)),
                       (ka.apply_relative(u, w), kb.apply_relative(u, w)),
                       (ka.jacobian_action(u, w), kb.jacobian_action(u, w)),
                       (ka.relative_jacobian_action(u, w, u), kb.relative_jacobian_action(u, w, u)),
                       (ka.jacobian_data(u), kb.jacobian_data(u)),
                       (ka.jacobian_data(u, newton=False), kb.jacobian_data(u, newton=False))):
            assert np.abs(va - vb).max() <= 1e-12 * np.abs(va).max()


def test_steady_navier_stokes_equal_on_both_paths():
    """Flow past a square in a channel at Re ~ 20: Newton on the fast reduced-Jacobian path
    with either assembly gives the same flow (measured 1.0e-13 relative, 5 iterations each)."""
    hole = np.array([[0.4, 0.6, 0.6, 0.4], [0.4, 0.4, 0.6, 0.6]])
    mesh = box(0.0, 0.0, 2.0, 1.0, 0.01, hole=hole)
    flows = [sg.solve_steady(sg.TaylorHood(mesh, assembly=a), sg.Fluid(1.0, 0.01),
                             {"wall": (1.0, 0.0), "particle0": (0.0, 0.0)}, convection=True)
             for a in ("compiled", "scikit-fem")]
    a, b = flows
    assert a.report.iterations == b.report.iterations >= 3
    assert np.abs(a.x - b.x).max() <= 1e-10 * np.abs(a.x).max()


def test_paper_single_particle_equal_on_both_paths():
    """The paper's single particle (1 ms, graded mesh moving with the particle): v_y equal
    to 1e-10 relative at every step (measured: 8e-16 at most, equal at 1 ms); the
    scikit-fem assembly cost 9.2x the compiled CPU time (4.50 s against 0.49 s)."""
    sc = replace(Scene.bundled("single_particle"), output_dir=None)
    vy = {a: np.array(Simulation(sc, assembly=a).run(progress=False).history.vy)
          for a in ("compiled", "scikit-fem")}
    assert vy["compiled"][-1] < -3e-3  # sinking at 3.9 mm/s
    assert np.abs(vy["scikit-fem"] / vy["compiled"] - 1.0).max() < 1e-10


def test_unknown_assembly_is_one_line():
    mesh = box(0.0, 0.0, 1.0, 1.0, 0.1)
    with pytest.raises(ValueError, match=r"assembly = 'numba': must be one of"):
        sg.TaylorHood(mesh, assembly="numba")
