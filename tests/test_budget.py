"""Budgets: steps, triangles and memory estimated before any work and checked against limits.

The triangle estimate is checked against the meshes built for every bundled
fluid scene (within a factor 3; measured 0.96 to 2.15); the refusals themselves
are rows of the bad-input table (tests/test_bad_input.py). A graded mesh with
``delta_l = 1e-7`` (measured before: 50 s and 5.9 GB, then a MemoryError) is
refused from its estimate before the mesher runs, by the simulation's budget and
by the mesher itself.
"""

from dataclasses import replace

import pytest

import meshing
from skfem_granular.coupled.build import build_mesh
from skfem_granular.dem import DEMSystem, Polygon
from skfem_granular.scene import MeshSpec, Scene, bundled_scenes
from skfem_granular.simulation import Budget, BudgetError, Simulation
from skfem_granular.simulation.budget import (
    BASE_MEMORY,
    Estimate,
    taylor_hood_unknowns,
    triangles,
)


def _cores(sc):
    dem = DEMSystem.in_box([p.to_dem() for p in sc.particles], sc.domain, sc.wall_thickness,
                           law=sc.contact_law, dt=sc.time.dem_dt)
    return dem.core_outlines()


@pytest.mark.parametrize("name", [n for n, p in bundled_scenes().items()
                                  if not Scene.from_toml(p).dry])
def test_triangle_estimate_within_a_factor_3_of_the_mesh(name):
    sc = Scene.bundled(name)
    cores = _cores(sc)
    built = build_mesh(sc, cores).mesh.t.shape[1]
    assert 1 / 3 < triangles(sc, cores) / built < 3


def test_unknowns_and_memory_follow_the_triangles():
    e = Estimate(steps=10, triangles=1000)
    assert e.unknowns == 4500 and e.memory == BASE_MEMORY + 4500 * 5000.0
    assert Estimate(10, 1000, "split").memory == BASE_MEMORY + 4500 * 2500.0


def test_taylor_hood_unknowns_are_the_spaces_dofs():
    """2 (vertices + edges) velocity and one pressure unknown per vertex: the DOFs of the
    library's Taylor-Hood space on the single particle's mesh."""
    import skfem_granular as sg

    mesh = build_mesh(Scene.bundled("single_particle"), _cores(Scene.bundled("single_particle")))
    space = sg.TaylorHood(mesh.mesh)
    assert taylor_hood_unknowns(mesh.mesh) == space.N


def test_default_memory_limit_is_what_the_machine_has(monkeypatch):
    """Without max_memory the refusal compares with the memory available now, names it,
    and comes before meshing (the 1000-grain column's ~1.5M unknowns need ~6.5 GB)."""
    from skfem_granular import memory

    sc = replace(Scene.bundled("single_particle"), output_dir=None)
    monkeypatch.setattr(memory, "available", lambda: 0.2e9)
    with pytest.raises(BudgetError, match=r"more than the 0.2 GB this machine has available"):
        Simulation(sc)
    monkeypatch.setattr(memory, "available", lambda: None)  # unknown: 16 GB
    Budget().check_mesh(sc, _cores(sc))
    with pytest.raises(BudgetError, match=r"1.5e\+06 unknowns \(monolithic coupling\) need "
                                          r"about 7.7 GB, more than max_memory = 4 GB"):
        Budget(max_memory=4e9).check_unknowns(sc, 1_500_000)


def test_built_mesh_is_checked_with_its_own_unknowns(monkeypatch):
    """An estimate below the limit and a mesh above it: refused after meshing, before any
    assembly (the coupled stepper is never built)."""
    from skfem_granular.simulation import run

    def never(*args, **kwargs):
        raise AssertionError("CoupledStepper built: the refusal came after assembly")

    monkeypatch.setattr(run, "CoupledStepper", never)
    monkeypatch.setattr("skfem_granular.simulation.budget.UNKNOWNS_PER_TRIANGLE", 1e-6)
    sc = replace(Scene.bundled("single_particle"), output_dir=None)
    with pytest.raises(BudgetError, match=r"\(the mesh built\): about 1.67e\+03 unknowns"):
        Simulation(sc, budget=Budget(max_memory=BASE_MEMORY + 100.0))


def test_graded_refusal_comes_before_any_meshing(monkeypatch):
    """Refused from the estimate: Triangle is never called (a mesh of 2.67e8 nodes would
    take hours and tens of GB)."""
    import triangle

    def never(*args, **kwargs):
        raise AssertionError("triangle.triangulate called: the refusal came after meshing")

    monkeypatch.setattr(triangle, "triangulate", never)
    sc = Scene.bundled("single_particle")
    sc = replace(sc, mesh=MeshSpec(kind="graded", delta_l=1e-7), output_dir=None)
    with pytest.raises(BudgetError, match=r"mesh.delta_l = 1e-07: the mesh would have about"):
        Simulation(sc)
    with pytest.raises(ValueError, match=r"the graded circles would hold 2.67e\+08 nodes"):
        meshing.graded_mesh((0, 0, 3e-3, 11e-3),
                            [Polygon.regular(24, 0.4e-3, center=(1.5e-3, 5.5e-3)).vertices],
                            delta_l=1e-7)


def test_a_raised_limit_lets_the_run_go():
    sc = replace(Scene.bundled("single_particle"), output_dir=None)
    with pytest.raises(BudgetError, match="more than max_elements = 100"):
        Simulation(sc, budget=Budget(max_elements=100))
    sim = Simulation(sc, budget=Budget(max_elements=400))  # the estimate: 398
    assert sim.mesh.t.shape[1] == 338


def test_a_million_particles_are_refused_before_parsing(tmp_path, capsys, monkeypatch):
    """10^6 [[particles]] entries (before: still parsing after 150 s at 0.95 GB): the file's
    size is refused before it is parsed (the TOML parser is never called)."""
    import tomllib

    from skfem_granular.cli import main

    def never(*args, **kwargs):
        raise AssertionError("tomllib.loads called: the refusal came after parsing")

    monkeypatch.setattr(tomllib, "loads", never)

    entry = ("[[particles]]\nsides = 6\nradius = 1e-5\ncenter = [1e-3, 1e-3]\n"
             "density = 2650.0\n")
    path = tmp_path / "million.toml"
    path.write_text("[domain]\nbox = [0.0, 0.0, 3e-3, 3e-3]\n" + entry * 10**6)
    assert main(["run", str(path), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "million.toml': 77 MB; at most 20 MB" in err[0], err


def test_a_refused_factorisation_stops_the_run_with_one_line(tmp_path, monkeypatch):
    """A factorisation refused for memory in the middle of a run ends it as a failed step
    does: one line, the history and the last good state written, the folder released."""
    from skfem_granular.fluid import superlu
    from skfem_granular.simulation import SimulationError

    calls = {"n": 0}
    factorize = superlu.SuperLUSolver.factorize

    def refuse_the_second(self, A, nu, **blocks):
        calls["n"] += 1
        if calls["n"] == 2:
            raise superlu.FactorizationMemoryError(
                "SuperLU: on 1436 unknowns ... would need about 9 GB, 1 GB left")
        return factorize(self, A, nu, **blocks)

    monkeypatch.setattr(superlu.SuperLUSolver, "factorize", refuse_the_second)
    sc = replace(Scene.bundled("single_particle"), output_dir=tmp_path / "run")
    sim = Simulation(sc)
    with pytest.raises(SimulationError, match=r"9 GB, 1 GB left; history and last good state "
                                              r"written to"):
        sim.run(progress=False)
    assert sim.status == "failed" and calls["n"] == 2
    assert (tmp_path / "run" / "history.csv").read_text().count("\n") >= 2
    assert not (tmp_path / "run" / ".skfem-granular.lock").exists()


def test_a_split_run_is_not_told_to_use_the_split_coupling():
    sc = replace(Scene.bundled("single_particle"), coupling="split", output_dir=None)
    with pytest.raises(BudgetError) as info:
        Budget(max_memory=1e6).check_unknowns(sc, 10_000)
    assert "(split coupling) need about 0.225 GB" in str(info.value)
    assert "the split coupling" not in str(info.value)
    with pytest.raises(BudgetError, match="use a coarser mesh, the split coupling, or raise"):
        Budget(max_memory=1e6).check_unknowns(replace(sc, coupling="monolithic"), 10_000)


@pytest.mark.parametrize("state", ["dense", "loose"])
def test_triangle_estimate_counts_the_gaps_lined_between_packed_grains(state, monkeypatch):
    """A packed column (30 near-disks, core ratio 0.9): the graded count alone misses the
    triangles lining the narrow gaps (measured 0.59-0.88 of the mesh on the dense columns
    of 25-1000 grains, 0.92 here); with the gap term the estimate is within 0.9-1.3 of
    the mesh (measured 1.02-1.16 on those columns, 1.15 and 1.20 here)."""
    from helpers import column_packing

    from skfem_granular.collapse import column_scene
    from skfem_granular.simulation import budget

    sc = column_scene(column_packing(state), fluid=True, core_ratio=0.9, t_end=2e-4,
                      dt=2e-4)
    dem = DEMSystem.in_box([p.to_dem() for p in sc.particles], sc.domain, sc.wall_thickness,
                           law=sc.contact_law, overlap_tolerance=sc.overlap_tolerance)
    cores = dem.core_outlines()
    built = build_mesh(sc, cores).mesh.t.shape[1]
    ratio = triangles(sc, cores) / built
    assert 0.9 < ratio < 1.3
    monkeypatch.setattr(budget, "LINED_SHARE", 0.0)  # the graded count alone
    assert triangles(sc, cores) / built < ratio - 0.15
