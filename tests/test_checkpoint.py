"""Checkpoints: a resumed run reproduces an uninterrupted one bit for bit."""

from dataclasses import replace

import numpy as np
import pytest

from skfem_granular.scene import Scene, TimeSpec, bundled
from skfem_granular.simulation import Simulation

SCENES = bundled("single_particle").parent  # the bundled scenes (skfem_granular/scene/library)
COLUMNS = ("t", "dt", "iterations", "x", "y", "angle", "vx", "vy", "omega", "Fx", "Fy", "torque")


def _with(scene, t_end, every=0):
    return replace(scene, time=TimeSpec(t_end=t_end, dt=scene.time.dt, dem_dt=scene.time.dem_dt),
                   checkpoint_every=every, vtu_every=4)


def _assert_same(h1, h2):
    assert len(h1) == len(h2)
    for c in COLUMNS:
        assert np.array_equal(getattr(h1, c), getattr(h2, c)), c


def _check_resume(scene, n_total, n_first, tmp_path):
    dt = scene.time.dt
    full = Simulation(_with(scene, n_total * dt, every=n_first), output_dir=tmp_path / "full")
    h_full = full.run(progress=False).history
    part = Simulation(_with(scene, n_first * dt, every=n_first), output_dir=tmp_path / "part")
    part.run(progress=False)
    resumed = Simulation.resume(tmp_path / "part", t_end=n_total * dt)
    h_res = resumed.run(progress=False).history
    _assert_same(h_full, h_res)
    return full, resumed


def test_resume_single_particle_bit_for_bit(tmp_path):
    scene = Scene.from_toml(SCENES / "single_particle.toml")
    full, resumed = _check_resume(scene, 20, 10, tmp_path)
    assert np.array_equal(full.last_good.x, resumed.last_good.x)  # fluid velocity and pressure
    assert np.array_equal(full.last_good.u_prev, resumed.last_good.u_prev)  # BDF2 history
    # the series continues: every frame time of the full run is in the resumed series
    # (which also has the frame the first part wrote at its end)
    from skfem_granular.viz import read_pvd

    t_full = {t for t, _ in read_pvd(tmp_path / "full" / "flow.pvd")}
    t_part = {t for t, _ in read_pvd(tmp_path / "part" / "flow.pvd")}
    assert t_full <= t_part and len(t_part) == len(t_full) + 1


def test_resume_with_contacts_and_remeshing_bit_for_bit(tmp_path):
    data = {"domain": {"box": [0.0, 0.0, 6e-3, 4e-3]},
            "fluid": {"density": 1000.0, "viscosity": 1e-3},
            "grid": {"nx": 2, "ny": 1, "sides": 6, "radius": 0.5e-3, "spacing": 1.1e-3,
                     "origin": [2.4e-3, 0.437e-3], "density": 2650.0, "core_ratio": 0.8},
            "mesh": {"kind": "group", "delta_l": 0.2e-3},
            "time": {"t_end": 3e-3, "dt": 2e-4},
            "coupling": {"remesh_fraction": 0.005}}
    scene = Scene.from_dict(data, name="floor")
    full, resumed = _check_resume(scene, 14, 7, tmp_path)
    assert resumed.remeshes >= 1 and resumed.contacts_active
    assert np.array_equal(full.last_good.x, resumed.last_good.x)


def test_resume_dry_scene_bit_for_bit(tmp_path):
    scene = replace(Scene.from_toml(SCENES / "single_particle.toml"), fluid=None)
    _check_resume(scene, 12, 6, tmp_path)


def test_resume_errors(tmp_path):
    with pytest.raises(ValueError, match="no checkpoint.pkl"):
        Simulation.resume(tmp_path)
    (tmp_path / "checkpoint.pkl").write_bytes(b"not a pickle")
    with pytest.raises(ValueError, match="not a readable checkpoint"):
        Simulation.resume(tmp_path)


def test_cli_resume(tmp_path, capsys):
    from skfem_granular.cli import main

    toml = (SCENES / "single_particle.toml").read_text().replace(
        "vtu_every = 10", "vtu_every = 5\ncheckpoint_every = 5")
    scene = tmp_path / "sp.toml"
    scene.write_text(toml)
    out = tmp_path / "out"
    assert main(["run", str(scene), "--out", str(out), "--t-end", "1e-4", "--no-progress"]) == 0
    assert main(["run", "--resume", str(out), "--t-end", "2e-4", "--no-progress"]) == 0
    table = np.loadtxt(out / "history.csv", delimiter=",", skiprows=1)
    assert table.shape[0] == 20 and table[-1, 0] == pytest.approx(2e-4)
    capsys.readouterr()
    assert main(["run", "--resume", str(tmp_path / "nothing")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no checkpoint.pkl" in err[0]


def test_resume_adaptive_run_bit_for_bit(tmp_path):
    """Adaptive steps: the proposed next step and the derivative histories are in the
    checkpoint, so the resumed run takes the same steps."""
    scene = Scene.from_toml(SCENES / "single_particle.toml")
    scene = replace(scene, time=replace(scene.time, adaptive=True, tol=1e-4))
    full = Simulation(replace(scene, time=replace(scene.time, t_end=2e-4), checkpoint_every=8),
                      output_dir=tmp_path / "full")
    h_full = full.run(progress=False).history
    part = Simulation(replace(scene, time=replace(scene.time, t_end=2e-4), checkpoint_every=8),
                      output_dir=tmp_path / "part")
    part.run(progress=False)  # writes checkpoints at 8, 16, ... steps; resume the last
    from skfem_granular.simulation import checkpoint

    k = checkpoint.load(tmp_path / "part")["k"]
    assert 0 < k < len(h_full)  # the resumed run takes steps of its own (measured 16 of 23)
    resumed = Simulation.resume(tmp_path / "part", t_end=2e-4)
    assert resumed.scene.time.adaptive and resumed.scene.time.tol == 1e-4
    h_res = resumed.run(progress=False).history
    _assert_same(h_full, h_res)
    assert np.array_equal(h_full.error, h_res.error, equal_nan=True)
    assert np.isfinite(h_full.error).any() and np.nanmax(h_full.error) <= 1e-4
