"""Repairing the moving mesh by edge flips (coupled.mesh_repair, MeshKeeper.repair)."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
import skfem

from meshing.flips import flip_repair, with_triangles
from skfem_granular.coupled.mesh_repair import flip_transfer
from skfem_granular.fluid import TaylorHood


def _quadratic(x):
    return 1.0 + 2.0 * x[0] - 3.0 * x[1] + 0.7 * x[0] ** 2 - 1.3 * x[0] * x[1] + 2.1 * x[1] ** 2


def test_flip_transfer_is_exact_for_quadratics():
    """A P2 field moved across flips in two configurations: every DOF of the flipped mesh
    holds the quadratic's value (vertices and kept edges copied, new edges' midpoints
    evaluated in the old triangles), to round-off."""
    m = skfem.MeshTri.init_circle(4)
    rng = np.random.default_rng(1)
    inner = np.setdiff1d(np.arange(m.p.shape[1]), m.boundary_nodes())
    configs = []
    for _ in range(2):
        p = m.p.copy()
        p[:, inner] += 0.008 * rng.standard_normal((2, inner.size))
        configs.append(p)
    t, changed = flip_repair(m.t, configs, 25.0)
    assert changed.size > 0
    old = TaylorHood(m)
    new = TaylorHood(with_triangles(m, t))
    for p in configs:
        u_old = _quadratic(old.moved(p).numbering("scalar").doflocs)
        want = _quadratic(new.moved(p).numbering("scalar").doflocs)
        got = flip_transfer(old, new, p, changed) @ u_old
        assert np.abs(got - want).max() < 1e-12 * np.abs(want).max()


def _loose_column(repair):
    from helpers import column_packing

    from skfem_granular.collapse import column_scene

    sc = column_scene(column_packing("loose"), fluid=True, core_ratio=0.9, t_end=8e-3, dt=2e-4)
    return replace(sc, coupling="split", mesh_repair=repair, output_dir=None)


def _grains(history):
    """Mean vertical velocity and mean squared speed of the grains at the end."""
    vx, vy = history.vx[-1], history.vy[-1]
    return np.array([vy.mean(), (vx**2 + vy**2).mean()])


def test_a_repaired_column_follows_the_remeshed_one_and_resumes_bit_for_bit(tmp_path):
    """30 loose grains released in water (split coupling, 40 steps): the one remesh the
    moved mesh asks for (a poor triangle one step ahead, after 36 steps) is answered by
    flipping 31 edges; at 8 ms the grains' mean velocity and mean squared speed are within
    0.5 % of the run that remeshed (measured 0.09 % and 0.14 %), and a checkpoint written on
    the repaired mesh resumes to the same numbers bit for bit."""
    from helpers import resumed_between_checkpoints

    from skfem_granular.simulation import Simulation

    ref, resumed = resumed_between_checkpoints(_loose_column("flips"), tmp_path, 38)
    summary = json.loads((tmp_path / "ref" / "summary.json").read_text())
    assert summary["remeshes"] == 0 and summary["mesh_repairs"]["done"] == 1
    remeshed = Simulation(_loose_column("none"))
    remeshed.run(progress=False)
    assert remeshed.remeshes == 1
    assert _grains(ref) == pytest.approx(_grains(remeshed.history), rel=5e-3)
    for c in ("vx", "vy", "omega", "Fy", "torque"):
        assert np.array_equal(getattr(ref, c), getattr(resumed, c)), c
