"""PARDISO: chosen by ``solver="auto"`` from a size on where installed, bitwise reproducible.

Where ``pypardiso`` is not installed, ``"auto"`` keeps SuperLU (simulated here by an
import that fails); where it is, PARDISO's solution matches SuperLU's and two fresh
processes with one and two MKL threads give the same bits (MKL's conditional numerical
reproducibility mode, ``PardisoSolver``'s default).
"""

import hashlib
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from helpers import annulus, coupled_run_through

import skfem_granular as sg
from skfem_granular.fluid import linsolve
from skfem_granular.fluid.linsolve import AUTO_KRYLOV_SIZE, AUTO_PARDISO_SIZE, make_solver

ROOT = Path(__file__).resolve().parents[1]

#: A Navier-Stokes solve (Newton: two patterns, refactorisations on a kept analysis)
#: printing the SHA-256 of the solution's bytes; run in fresh processes.
SCRIPT = """
import hashlib, sys
sys.path.insert(0, {tests!r})
from helpers import annulus, coupled_run_through
import skfem_granular as sg
mesh = annulus(1.0, 2.0, 24, 48, 0.01)
bc = {{"inner": (1.0, 0.0), "outer": (0.0, 0.0)}}
flow = sg.solve_steady(mesh, sg.Fluid(1.0, 0.05), bc, True, solver="pardiso")
print(flow.report.iterations, hashlib.sha256(flow.x.tobytes()).hexdigest())
"""


def _has_pardiso() -> bool:
    try:
        import pypardiso  # noqa: F401
    except ImportError:
        return False
    return True


needs_pardiso = pytest.mark.skipif(not _has_pardiso(), reason="pypardiso not installed")


def test_auto_keeps_superlu_when_pypardiso_does_not_import(monkeypatch):
    monkeypatch.setitem(sys.modules, "pypardiso", None)  # import pypardiso -> ImportError
    monkeypatch.setattr(linsolve, "_PARDISO_AVAILABLE", None)
    monkeypatch.setattr(linsolve, "_PYPARDISO_TEMPLATE", None)
    assert make_solver("auto", AUTO_PARDISO_SIZE).name == "superlu"
    assert make_solver("auto", AUTO_KRYLOV_SIZE + 1).name == "krylov"
    with pytest.raises(ValueError, match="pypardiso"):
        make_solver("pardiso")


@needs_pardiso
def test_auto_takes_pardiso_from_its_size_on(monkeypatch):
    monkeypatch.setattr(linsolve, "_PARDISO_AVAILABLE", None)
    assert make_solver("auto", AUTO_PARDISO_SIZE - 1).name == "superlu"
    for size in (AUTO_PARDISO_SIZE, 10 * AUTO_PARDISO_SIZE):
        s = make_solver("auto", size)
        assert s.name == "pardiso" and s.reproducible
    # a matrix factorised once (a Stokes solve) stays with SuperLU: PARDISO's analysis
    # made the 95k-unknown DFG Stokes solve 3.0 s against SuperLU's 2.0 s
    assert make_solver("auto", AUTO_PARDISO_SIZE, once=True).name == "superlu"


@needs_pardiso
def test_pardiso_matches_superlu_and_repeats_its_bits():
    mesh = annulus(1.0, 2.0, 24, 48, 0.01)
    bc = {"inner": (1.0, 0.0), "outer": (0.0, 0.0)}
    fluid = sg.Fluid(1.0, 0.05)
    ref = sg.solve_steady(mesh, fluid, bc, True, solver="superlu")
    runs = [sg.solve_steady(mesh, fluid, bc, True, solver="pardiso") for _ in range(2)]
    assert ref.report.iterations == runs[0].report.iterations >= 3
    assert np.linalg.norm(runs[0].x - ref.x) < 1e-10 * np.linalg.norm(ref.x)
    assert runs[0].x.tobytes() == runs[1].x.tobytes()  # same process, twice
    stokes = sg.solve_steady(mesh, fluid, bc, solver="pardiso")
    stokes_ref = sg.solve_steady(mesh, fluid, bc, solver="superlu")
    assert np.linalg.norm(stokes.x - stokes_ref.x) < 1e-10 * np.linalg.norm(stokes_ref.x)


@needs_pardiso
def test_pardiso_bits_equal_in_fresh_processes_with_one_and_two_threads():
    code = SCRIPT.format(tests=str(ROOT / "tests"))
    out = []
    for threads in ("1", "2"):
        env = dict(os.environ, MKL_NUM_THREADS=threads, OMP_NUM_THREADS=threads,
                   PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
        res = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                             text=True, timeout=300, check=True)
        out.append(res.stdout.split())
    assert out[0] == out[1], out
    here = sg.solve_steady(annulus(1.0, 2.0, 24, 48, 0.01), sg.Fluid(1.0, 0.05),
                           {"inner": (1.0, 0.0), "outer": (0.0, 0.0)}, True, solver="pardiso")
    assert hashlib.sha256(here.x.tobytes()).hexdigest() == out[0][1]


@needs_pardiso
@pytest.mark.skipif(not Path("/proc/self/statm").exists(), reason="needs /proc (Linux)")
def test_a_dropped_pardiso_solver_releases_its_factors():
    """MKL holds PARDISO's factors outside Python until phase -1: a solver dropped (one
    per remesh) must release them. Without it every dropped solver of this matrix kept
    ~240 MB (8 solvers: +1.9 GB); with it the resident size stays flat.

    What one factorisation holds is MKL's own figure (about 94 MB here): the resident
    size's growth at the first factorisation depends on what the allocator already
    had (in one full run it came out at 5 MB or less, after earlier tests freed memory)."""
    from skfem_granular.fluid.boundary import DirichletData
    from skfem_granular.fluid.operator import NavierStokesOperator

    def resident_mb():
        return int(Path("/proc/self/statm").read_text().split()[1]) * os.sysconf(
            "SC_PAGE_SIZE") / 1e6

    space = sg.TaylorHood(annulus(1.0, 2.0, 48, 96, 0.002))
    op = NavierStokesOperator(space, sg.Fluid(), DirichletData(
        space, {"inner": (1.0, 0.0), "outer": (0.0, 0.0)}))
    _, J, nu, blocks = op.reduced_bdf2_system(100.0)
    s = linsolve.PardisoSolver()
    assert s.factor_memory_mb == 0.0
    s.factorize(J, nu, **blocks)
    held = s.factor_memory_mb  # what one live factorisation takes, as MKL reports it
    del s
    after_one = resident_mb()
    for _ in range(4):
        s = linsolve.PardisoSolver()
        s.factorize(J, nu, **blocks)
        del s
    assert held > 50.0  # 5.85M factor entries: at least 47 MB of them
    assert resident_mb() - after_one < 0.5 * held


@needs_pardiso
def test_a_coupled_run_on_pardiso_matches_superlu(monkeypatch):
    """The monolithic coupled step through PARDISO (what ``"auto"`` picks from
    AUTO_PARDISO_SIZE unknowns on, lowered here to 0): the paper's particle over 20 steps
    follows the SuperLU run to round-off in its velocity and position."""
    h, ref, solver = coupled_run_through(monkeypatch, "AUTO_PARDISO_SIZE")
    assert solver == "pardiso"
    np.testing.assert_allclose(h.vy, ref.vy, rtol=1e-9, atol=1e-12 * np.abs(ref.vy).max())
    np.testing.assert_allclose(h.y, ref.y, rtol=1e-12)
