"""The wake-aware default mesh on quiet flows: the same numbers, the same cost.

Runs the paper's single particle (``single_particle``, 1 ms) and the low-Re settling disk
(``settling_disk_channel``, 1 s: Glowinski et al.'s and Wan & Turek's set-up) with the
wake rule (``[mesh] wake = true``, the default) and without it (``wake = false``: the
default mesh before the rule), ``--repeats`` times each, interleaved. Records whether the
histories are bit-identical (and the largest relative difference of every column), the
largest particle Reynolds number, the remeshes, and the CPU time (``time.process_time``)
of every run. CPU times of whole runs vary by 10-20 % on a shared machine, so the work the
rule adds (one Reynolds number per particle before every step: ``MeshKeeper._wake_options``) is also
timed by itself, ``--calls`` times, and reported as a fraction of a run's CPU time.

Writes ``benchmarks/results/wake_quiet.json``.

Usage: ``python benchmarks/wake_quiet.py [--repeats 2]``
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from skfem_granular.scene import Scene
from skfem_granular.simulation import Simulation

ROOT = Path(__file__).resolve().parents[1]
SCENES = ("single_particle", "settling_disk_channel")
COLUMNS = ("x", "y", "angle", "vx", "vy", "omega", "Fx", "Fy", "torque")


def run(name: str, wake: bool):
    """One run of bundled scene ``name``: (history, remeshes, CPU seconds, core radii)."""
    sc = Scene.bundled(name)
    sc = replace(sc, mesh=replace(sc.mesh, wake=wake), output_dir=None)
    sim = Simulation(sc)
    c0 = time.process_time()
    h = sim.run(progress=False).history
    return h, sim.remeshes, time.process_time() - c0, sim.stepper.radius


def check_cost(name: str, calls: int) -> float:
    """CPU seconds of one wake check (the per-step work the rule adds) on scene ``name``."""
    sc = replace(Scene.bundled(name), output_dir=None)
    st = Simulation(sc).stepper
    c0 = time.process_time()
    for _ in range(calls):
        st.keeper._wake_options()
    return (time.process_time() - c0) / calls


def compare(a, b) -> dict:
    """Bit-identical or not, and the largest difference relative to each column's size."""
    out = {"identical": bool(all(np.array_equal(getattr(a, c), getattr(b, c))
                                 for c in ("t", *COLUMNS)))}
    for c in COLUMNS:
        x, y = getattr(a, c), getattr(b, c)
        scale = float(np.abs(x).max()) or 1.0
        out[c] = float(np.abs(x - y).max() / scale)
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--calls", type=int, default=20_000)
    a = ap.parse_args()
    out = {"benchmark": "wake_quiet", "scenes": {}}
    for name in SCENES:
        runs = {True: [], False: []}
        for _ in range(a.repeats):
            for wake in (False, True):
                runs[wake].append(run(name, wake))
        h_on, h_off = runs[True][0][0], runs[False][0][0]
        sc = Scene.bundled(name)
        d = 2.0 * runs[True][0][3]
        re = float((np.hypot(h_on.vx, h_on.vy) * d).max() / sc.fluid.kinematic_viscosity)
        cpu_on = [r[2] for r in runs[True]]
        cpu_off = [r[2] for r in runs[False]]
        out["scenes"][name] = {
            "t_end": float(h_on.t[-1]), "steps": len(h_on.t), "re_max": re,
            "remeshes": {"wake": runs[True][0][1], "no_wake": runs[False][0][1]},
            "difference": compare(h_on, h_off),
            "cpu_s": {"wake": cpu_on, "no_wake": cpu_off},
            "cpu_ratio_min": min(cpu_on) / min(cpu_off),
            "cpu_ratio_median": float(np.median(cpu_on) / np.median(cpu_off)),
            "check_cpu_s": (c := check_cost(name, a.calls)),
            "check_fraction": c * len(h_on.t) / min(cpu_off)}
        print(name, json.dumps(out["scenes"][name]))
    out["machine"] = platform.platform()
    out["commit"] = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                                   capture_output=True, text=True).stdout.strip()
    (ROOT / "benchmarks/results/wake_quiet.json").write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
