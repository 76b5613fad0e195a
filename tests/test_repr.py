"""Reprs say what an object holds, in one line, with its numbers."""

from dataclasses import replace

import numpy as np

import meshing
from skfem_granular.fluid.space import TaylorHood
from skfem_granular.scene import Effects, Scene
from skfem_granular.simulation import Simulation


def test_reprs_name_their_numbers():
    sc = replace(Scene.bundled("single_particle"), output_dir=None)
    r = repr(sc)
    assert r.startswith("Scene('single_particle': 1 particles") and "\n" not in r
    assert f"t_end={sc.time.t_end:g} s" in r and "fluid rho=" in r
    sim = Simulation(sc)
    space = sim.space
    assert repr(space) == (f"TaylorHood(P2/P1 on {space.mesh.p.shape[1]} vertices, "
                           f"{space.mesh.t.shape[1]} triangles: {space.nu} velocity + "
                           f"{space.np_} pressure = {space.N} unknowns)")
    assert space.N == space.nu + space.np_
    st = repr(sim.stepper)
    assert f"{space.N} unknowns" in st and "1 particles" in st and "t=0 s" in st
    assert st.split("(", 1)[1].rstrip(")") in repr(sim)
    assert repr(sim.dem).startswith("DEMSystem(1 particles, 4 walls, t=0 s after 0 steps")
    dry = Simulation(replace(sc, effects=Effects(fluid=False)))
    assert "dry" in repr(dry) and "no output" in repr(dry)


def test_mesh_reprs():
    th = 2 * np.pi * np.arange(24) / 24
    disk = np.vstack([1.5e-3 + 5e-4 * np.cos(th), 5.5e-3 + 5e-4 * np.sin(th)])
    value = meshing.build("graded", (0, 0, 3e-3, 11e-3), [disk])
    m = value.mesh
    assert repr(value) == (f"BodyFittedMesh('graded': {m.p.shape[1]} vertices, "
                           f"{m.t.shape[1]} triangles, 1 particles)")
    r = repr(value.recipe)
    assert r.startswith("Recipe('graded', domain=(0, 0, 0.003, 0.011), 1 particles")
    assert "[" not in r
    assert repr(TaylorHood(m)).startswith(f"TaylorHood(P2/P1 on {m.p.shape[1]} vertices")
