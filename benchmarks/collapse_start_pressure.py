"""Excess pore pressure under loose and dense columns as they start to move, over seeds.

Usage::

    python benchmarks/collapse_start_pressure.py                      # 200 grains, seeds 0 1 2
    python benchmarks/collapse_start_pressure.py --n 30 --steps 10    # a quick look

Rondon et al. (2011) and Kumar et al. tell loose from dense columns in a fluid by the
sign of the pore pressure as the collapse starts: a dense packing dilates as it shears
and sucks fluid in (negative excess pressure), a loose one contracts and pushes fluid out
(positive). The full runs (:mod:`collapse_matrix`) keep a flow frame every 250 steps, too
few for the first tenths of ``tau_c``; this benchmark releases the same columns (the same
packings, :func:`collapse_matrix.packing`, the same scene) in water for ``--steps`` steps
of 0.2 ms, without output, and every ``--every`` steps reads the excess pore pressure
(:func:`skfem_granular.collapse.excess_pressure`, relative to the still fluid at the
tank's top right corner) along the base (0.02 d_mean above the floor) and 10 d_mean
above it, averaged over the column's foot (from ``d_max / 2`` to ``L0 - d_max / 2``;
points inside grain cores are left out), over ``(rho_p - rho_f) g H0``. Per state and
core ratio: the mean and spread over the seeds at every sampled time
(:func:`skfem_granular.collapse.realisations`), and of each seed's mean over the
window (the pressure oscillates with the contacts, over about 0.1 ``tau_c``). Results:
``benchmarks/results/collapse_start_pressure_<tag>.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
from collapse_matrix import packing

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks/results"
DT = 2e-4


def window(n: int, state: str, core: float, seed: int, steps: int, every: int) -> dict:
    """One release: the mean excess pressure under the column every ``every`` steps."""
    from skfem_granular.collapse import (
        column_scene,
        excess_pressure,
        line_points,
        reference_point,
        time_scale,
    )
    from skfem_granular.simulation import Simulation

    pk = packing(n, state, seed)
    scene = column_scene(pk, fluid=True, core_ratio=core, t_end=steps * DT, dt=DT,
                         name=f"start_{state}_{seed}", output_dir=None)
    c0 = time.process_time()
    sim = Simulation(scene)
    ref = reference_point(scene.domain, pk.d_max)
    x0 = scene.domain[0]
    lines = {"base": 0.02 * pk.d_mean, "10d": 10 * pk.d_mean}
    P = {k: line_points(x0 + 0.5 * pk.d_max, x0 + pk.width - 0.5 * pk.d_max,
                        scene.domain[1] + y, n=100) for k, y in lines.items()}
    scale = (pk.density - scene.fluid.density) * 9.81 * pk.height
    rec: dict = {"t_over_tau": [], **{k: [] for k in lines}}

    def sample(t):
        flow = sim.stepper.flow()
        rec["t_over_tau"].append(t / time_scale(pk))
        for k, pts in P.items():
            rec[k].append(float(np.nanmean(excess_pressure(flow, pts, ref))) / scale)

    sample(0.0)
    for t, _ in sim.evolve(progress=False):
        if sim.steps_done % every == 0:
            sample(t)
    return {"state": state, "core_ratio": core, "seed": seed, "grains": pk.n,
            "solid_fraction": pk.solid_fraction, "cpu_s": time.process_time() - c0, **rec}


def summarise(runs: list) -> list:
    """Mean and spread over the seeds at every sampled time, per state and core ratio."""
    from skfem_granular.collapse import realisations

    out = []
    for key in sorted({(r["state"], r["core_ratio"]) for r in runs}):
        rs = [r for r in runs if (r["state"], r["core_ratio"]) == key]
        m = min(len(r["t_over_tau"]) for r in rs)
        out.append({"state": key[0], "core_ratio": key[1], "seeds": [r["seed"] for r in rs],
                    # the window's mean (after release) per seed, then over the seeds
                    **{f"{k}_window_mean": realisations([np.mean(r[k][1:]) for r in rs])
                       for k in ("base", "10d")},
                    "t_over_tau": rs[0]["t_over_tau"][:m],
                    **{k: [realisations([r[k][i] for r in rs]) for i in range(m)]
                       for k in ("base", "10d")}})
    return out


def rewrite_summary(out: Path) -> None:
    """Recompute the summary of a results file from its runs."""
    data = json.loads(out.read_text())
    data["summary"] = summarise(data["runs"])
    out.write_text(json.dumps(data, indent=1) + "\n")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--states", nargs="+", default=["dense", "loose"])
    ap.add_argument("--cores", type=float, nargs="+", default=[0.7])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--steps", type=int, default=60)
    ap.add_argument("--every", type=int, default=5)
    ap.add_argument("--tag", default=None)
    a = ap.parse_args(argv)
    out = RESULTS / f"collapse_start_pressure_{a.tag or f'n{a.n}'}.json"
    runs = json.loads(out.read_text())["runs"] if out.exists() else []
    for seed in a.seeds:
        for state in a.states:
            for core in a.cores:
                runs = [r for r in runs if (r["state"], r["core_ratio"], r["seed"])
                        != (state, core, seed)]
                runs.append(window(a.n, state, core, seed, a.steps, a.every))
                r = runs[-1]
                print(f"{state} core {core:g} seed {seed}: base {r['base'][-1]:+.4f}, "
                      f"10 d {r['10d'][-1]:+.4f} at t/tau {r['t_over_tau'][-1]:.3f} "
                      f"({r['cpu_s']:.0f} CPU s)", flush=True)
                out.write_text(json.dumps({"benchmark": "collapse_start_pressure",
                                           "cpus": os.cpu_count(), "dt": DT,
                                           "runs": runs, "summary": summarise(runs)},
                                          indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
