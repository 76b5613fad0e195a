"""Killed runs: every file left is complete, and resuming gives the uninterrupted run bit for bit.

``skfem-granular run`` runs in a subprocess and is killed at a random step
(seeded targets: the kill comes once the history shows that many rows, after
a random fraction of a step more, so it lands anywhere, inside a write too):

- SIGKILL: nothing is written after the kill. Every file present must be
  complete and readable (VTU frames, both PVD indices and the frames they
  name, ``history.csv`` with only complete lines and at least the
  checkpoint's rows, ``checkpoint.npz``); only hidden ``.partial-*`` files may
  be half written, and resuming removes them. The resumed run's output
  (history, PVD indices, every VTU file) equals the uninterrupted run's
  byte for byte.
- SIGTERM: the run stops at the end of the current step, writes a
  checkpoint, the history and a summary saying so, and exits with 143; the
  resumed run again equals the uninterrupted one.
- In the slow suite: a chain of 5 kills per run (each kill of a resumed run),
  for the single particle, for grains with contacts and remeshing, and for the
  paper's collapse to 0.06 s (across its remeshes and the first grain contacts).

The default suite's two subprocess tests take about 5 s each.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import meshio
import numpy as np
import pytest

from skfem_granular.cli import main
from skfem_granular.io import read_csv, read_pvd
from skfem_granular.simulation import Simulation, checkpoint

SEED = 16
SINGLE = ["single-particle", "--t-end", "3e-4", "--vtu-every", "2", "--checkpoint-every", "5"]
LOCK = ".skfem-granular.lock"  # a killed run leaves its lock; the next run takes it over
KNOWN = {"history.csv", "summary.json", "checkpoint.npz", "checkpoint.prev.npz", "flow.pvd",
         "particles.pvd", LOCK}
FLOOR_TOML = """\
# two hexagons dropped onto the floor: contacts and remeshing
[domain]
box = [0.0, 0.0, 6.0e-3, 4.0e-3]
[fluid]
density = 1000.0
viscosity = 1.0e-3
[grid]
nx = 2
ny = 1
sides = 6
radius = 0.5e-3
spacing = 1.1e-3
origin = [2.4e-3, 0.437e-3]
density = 2650.0
core_ratio = 0.8
[mesh]
kind = "group"
delta_l = 0.2e-3
[time]
t_end = 6.0e-3
dt = 2.0e-4
[coupling]
remesh_fraction = 0.005
remesh_travel = 0.005
"""


def _rows(path: Path) -> int:
    """Complete data lines of a history file (0 if there is none yet)."""
    try:
        text = path.read_text()
    except FileNotFoundError:
        return 0
    return max(0, text.count("\n") - 1)


def _ino(path: Path):
    try:
        return path.stat().st_ino
    except FileNotFoundError:
        return None


def _launch(argv, cwd):
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen([sys.executable, "-m", "skfem_granular.cli", "run", *argv,
                             "--no-progress"], cwd=cwd, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _kill_when(proc, history: Path, old_ino, rows: int, delay: float, sig, timeout=120.0):
    """Send ``sig`` once ``history`` (a new file, not ``old_ino``) has ``rows`` rows and
    ``delay`` seconds more have passed; returns the rows seen at the kill."""
    t0 = time.monotonic()
    while True:
        if proc.poll() is not None:
            out, err = proc.communicate()
            raise AssertionError(f"the run ended (code {proc.returncode}) before {rows} rows: "
                                 f"{err[-2000:]}")
        if _ino(history) not in (None, old_ino) and _rows(history) >= rows:
            break
        if time.monotonic() - t0 > timeout:
            proc.kill()
            raise AssertionError(f"no {rows} rows in {timeout} s")
        time.sleep(0.002)
    time.sleep(delay)
    seen = _rows(history)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=timeout)
    return seen, err


def _assert_complete(out: Path, *, finished: bool = False) -> int:
    """Every file present is whole and readable; returns the checkpoint's step (or 0)."""
    names = {p.name for p in out.iterdir()}
    partial = {n for n in names if n.startswith(".partial-")}
    frames = {n for n in names - partial - KNOWN}
    assert all(n.endswith(".vtu") and n.split("_")[0] in ("flow", "particles") for n in frames), \
        frames
    if finished:
        assert not partial, partial
        assert LOCK not in names  # released at the end
    for n in sorted(frames):
        m = meshio.read(out / n)
        assert m.points.shape[0] > 0
    for series in ("flow", "particles"):
        if (out / f"{series}.pvd").exists():
            listed = read_pvd(out / f"{series}.pvd")
            assert listed and all(f.exists() for _, f in listed)
    k = 0
    if (out / "checkpoint.npz").exists():
        k = checkpoint.load(out)["k"]
    if (out / "history.csv").exists():
        text = (out / "history.csv").read_text()
        assert text.endswith("\n"), "the history's last line is torn"
        cols = read_csv(out / "history.csv")
        assert cols["t"].shape[0] >= k  # the history has at least the checkpoint's rows
        assert np.all(np.isfinite(cols["t"])) and np.all(np.diff(cols["t"]) > 0)
    if (out / "summary.json").exists():
        json.loads((out / "summary.json").read_text())
    return k


def _assert_same(ref: Path, out: Path):
    """The resumed output equals the uninterrupted run's, file for file, byte for byte."""
    for name in ("history.csv", "flow.pvd", "particles.pvd"):
        assert (out / name).read_bytes() == (ref / name).read_bytes(), name
    vtu_ref = sorted(p.name for p in ref.glob("*.vtu"))
    assert sorted(p.name for p in out.glob("*.vtu")) == vtu_ref
    for n in vtu_ref:
        assert (out / n).read_bytes() == (ref / n).read_bytes(), n
    s_ref = json.loads((ref / "summary.json").read_text())
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "completed" and s["final"] == s_ref["final"]
    assert s["steps"] == s_ref["steps"]


def _reference(argv, tmp_path, capsys):
    ref = tmp_path / "reference"
    assert main(["run", *argv, "--out", str(ref), "--no-progress"]) == 0
    capsys.readouterr()
    return ref


def _resume(out, capsys):
    assert main(["run", "--resume", str(out), "--no-progress"]) == 0
    capsys.readouterr()


def test_sigkill_at_a_random_step_then_resume_bit_for_bit(tmp_path, capsys):
    rng = np.random.default_rng(SEED)
    rows, delay = int(rng.integers(8, 24)), float(rng.uniform(0.0, 0.02))
    out = tmp_path / "killed"
    proc = _launch([*SINGLE, "--out", str(out)], tmp_path)
    seen, _ = _kill_when(proc, out / "history.csv", None, rows, delay, signal.SIGKILL)
    assert proc.returncode == -signal.SIGKILL
    k = _assert_complete(out)
    with capsys.disabled():
        print(f"\nSIGKILL after {seen} history rows (target {rows}, +{delay * 1e3:.1f} ms); "
              f"checkpoint at step {k}")
    assert k >= 5 and not (out / "summary.json").exists()
    ref = _reference(SINGLE, tmp_path, capsys)
    _resume(out, capsys)
    _assert_complete(out, finished=True)
    _assert_same(ref, out)


def test_sigterm_stops_at_the_end_of_a_step_and_writes_everything(tmp_path, capsys):
    rng = np.random.default_rng(SEED + 1)
    rows = int(rng.integers(8, 24))
    out = tmp_path / "stopped"
    proc = _launch([*SINGLE, "--out", str(out)], tmp_path)
    _, err = _kill_when(proc, out / "history.csv", None, rows, float(rng.uniform(0.0, 0.02)),
                        signal.SIGTERM)
    assert proc.returncode == 128 + signal.SIGTERM, err
    assert "stopped by SIGTERM" in err and "--resume" in err
    k = _assert_complete(out, finished=True)
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "stopped" and s["stopped_by"] == "SIGTERM" and s["failed"] is None
    h = read_csv(out / "history.csv")
    assert s["steps"] == k == h["t"].shape[0] >= rows  # stopped after a whole step
    assert h["t"][-1] == pytest.approx(s["t_end"], rel=1e-12)
    ref = _reference(SINGLE, tmp_path, capsys)
    _resume(out, capsys)
    _assert_same(ref, out)


@pytest.mark.parametrize("name", ["SIGINT", "SIGTERM"])
def test_signal_in_process_stops_the_loop_and_restores_handlers(tmp_path, name):
    """The generator loop ends after the step in which the signal came; handlers restored."""
    from dataclasses import replace

    from skfem_granular.scene import Scene

    sig = getattr(signal, name)
    before = signal.signal(signal.SIGINT, signal.default_int_handler)  # even if ignored here
    try:
        mine = signal.getsignal(sig)
        sc = Scene.bundled("single_particle")
        sim = Simulation(replace(sc, time=replace(sc.time, t_end=1e-4)), output_dir=tmp_path)
        steps = 0
        for _ in sim.evolve():
            steps += 1
            if steps == 3:
                signal.raise_signal(sig)
        assert steps == 3 and signal.getsignal(sig) is mine
        s = sim.result.summary
        assert (s["status"], s["stopped_by"], s["steps"]) == ("stopped", name, 3)
        assert checkpoint.load(tmp_path)["k"] == 3  # written although checkpoint_every = 0
        assert read_csv(tmp_path / "history.csv")["t"].shape == (3,)
    finally:
        signal.signal(signal.SIGINT, before)


def _chain(argv, n_total, tmp_path, capsys, seed, kills=5, targets=None):
    """Kill a run ``kills`` times at random steps (or at the history rows ``targets``), each
    time resuming the killed run."""
    rng = np.random.default_rng(seed)
    out = tmp_path / "chain"
    points = []
    k = 0
    if targets is None:
        targets = np.sort(rng.choice(np.arange(3, n_total - 2), size=kills, replace=False))
    for target in targets:
        rows = max(int(target), k + 2)  # beyond the checkpoint the killed run resumes from
        delay = float(rng.uniform(0.0, 0.03))
        old = _ino(out / "history.csv")
        fresh = not (out / "checkpoint.npz").exists()
        proc = _launch([*argv, "--out", str(out)] if fresh else ["--resume", str(out)], tmp_path)
        seen, _ = _kill_when(proc, out / "history.csv", old, rows, delay, signal.SIGKILL,
                             timeout=600.0)
        assert proc.returncode == -signal.SIGKILL
        k = _assert_complete(out)
        points.append((seen, k))
    with capsys.disabled():
        print(f"\nkills (history rows seen, checkpoint step after the kill): {points}")
    ref = _reference(argv, tmp_path, capsys)
    _resume(out, capsys)
    _assert_complete(out, finished=True)
    _assert_same(ref, out)
    return points


@pytest.mark.slow
def test_five_sigkills_single_particle(tmp_path, capsys):
    argv = ["single-particle", "--t-end", "6e-4", "--vtu-every", "2", "--checkpoint-every", "4"]
    points = _chain(argv, 60, tmp_path, capsys, SEED + 2)
    assert len(points) == 5


@pytest.mark.slow
def test_five_sigkills_contacts_and_remeshing(tmp_path, capsys):
    scene = tmp_path / "floor.toml"
    scene.write_text(FLOOR_TOML)
    argv = [str(scene), "--vtu-every", "2", "--checkpoint-every", "3"]
    points = _chain(argv, 30, tmp_path, capsys, SEED + 3)
    assert len(points) == 5
    s = json.loads((tmp_path / "chain" / "summary.json").read_text())
    assert s["effects"]["contacts"] and s["remeshes"] >= 1


@pytest.mark.slow
def test_sigkills_across_the_collapse(tmp_path, capsys):
    """The paper's collapse (25 grains) to 0.06 s, 300 steps: killed with SIGKILL at five
    points spread over the run, before and after the first grain contact (step 157) and
    between its 21 remeshes, each time resumed; the output equals the uninterrupted run's
    byte for byte. 5 min 16 s on 2 busy cores (the run alone: 68 s)."""
    argv = ["collapse", "--t-end", "0.06", "--vtu-every", "25", "--checkpoint-every", "10"]
    points = _chain(argv, 300, tmp_path, capsys, SEED + 4, targets=[45, 130, 175, 230, 285])
    assert len(points) == 5 and points[-1][1] >= 250  # the last kill after contacts began
    s = json.loads((tmp_path / "chain" / "summary.json").read_text())
    assert s["effects"]["contacts"] and s["remeshes"] >= 20
    h = read_csv(tmp_path / "chain" / "history.csv")
    contacts = sum(h[c] for c in h if c.startswith("contacts"))
    first = int(np.flatnonzero(contacts > 0)[0])
    assert first < 175  # grains touch before the later kills
