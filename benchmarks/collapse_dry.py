"""Benchmark: dry column collapses (DEM only) against the published 2D run-out laws.

Usage: ``python benchmarks/collapse_dry.py [--n 200] [--aspects 0.5 0.8 2 4]
[--seeds 0 1 2] [--state dense] [--shape ngon] [--tag NAME]``.

For every (aspect, seed): a column of ``n`` grains is prepared
(:func:`skfem_granular.packing.prepare_column`: 12-gon near-disks, d_mean = 1 mm,
d_max / d_min = 1.8, E = 1e6 N/m), placed in a dry tank
(:func:`skfem_granular.collapse.column_scene`, ``fluid=False``, friction tan 26 deg,
damping 0.5) and released; the run stops when the grains' kinetic energy has fallen
below 1e-2 of its peak, or below 5e-2 of it with a front that has moved less than
0.005 L0 over the last tau_c (after at least 3 tau_c), or at 12 tau_c. The final run-out
``(L_inf - L0) / L0`` (front: right end of the grains connected to the wall) is
compared with the laws of :mod:`skfem_granular.collapse.laws`. This is the first
comparison's rule, kept for its results; a run to rest with the deposit's front read
as the published 2D DEM study reads it is :func:`skfem_granular.collapse.run_dry`
(``benchmarks/collapse_factors.py`` compares the two, docs/collapse.md). Writes
``benchmarks/results/collapse_dry_<tag>.json``: every run, and per aspect the mean and
spread (sample standard deviation, min, max) over the seeds.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from skfem_granular.collapse import (
    DRY_LAWS,
    collapse_series,
    column_scene,
    dry_runout,
    front_position,
    realisations,
    time_scale,
)
from skfem_granular.packing import prepare_column
from skfem_granular.simulation import Simulation

RESULTS = Path(__file__).resolve().parent / "results"


def collapse(packing, stop_ratio=1e-2, t_max_tau=12.0, creep=5e-3):
    """Run the dry collapse until the deposit stops; the series of :func:`collapse_series`."""
    tau = time_scale(packing)
    scene = column_scene(packing, fluid=False, t_end=t_max_tau * tau)
    sim = Simulation(scene)
    peak = 0.0
    fronts = []
    for t, _ in sim.evolve():
        E = sim.dem.kinetic_energy()
        peak = max(peak, E)
        fronts.append((t, front_position(sim.dem.shadow_outlines())))
        back = [f for s, f in fronts if s <= t - tau]
        crept = fronts[-1][1] - back[-1] if back else np.inf
        slow = E < stop_ratio * peak or (E < 5 * stop_ratio * peak
                                         and crept < creep * packing.width)
        if t > 3.0 * tau and slow:
            break
    return collapse_series(sim.history, packing, scene.domain), scene


def run(n, aspect, seed, state, shape):
    t0 = time.perf_counter()
    p = prepare_column(n, aspect, state, shape=shape, seed=seed)
    t1 = time.perf_counter()
    s, scene = collapse(p)
    row = {"n": n, "aspect_wanted": aspect, "aspect": p.aspect, "seed": seed, "state": state,
           "shape": shape, "solid_fraction": p.solid_fraction, "L0": p.width, "H0": p.height,
           "tank": list(scene.domain), "runout": float(s["runout"][-1]),
           "t_stop_over_tau": float(s["t_over_tau"][-1]),
           "gate_height": float(s["gate_height"][-1]),
           "E_final_over_peak": float((s["E_x"] + s["E_y"])[-1] / (s["E_x"] + s["E_y"]).max()),
           "laws": {k: float(dry_runout(p.aspect, k)) for k in DRY_LAWS},
           "packing_wall_s": t1 - t0, "collapse_wall_s": time.perf_counter() - t1,
           "runout_curve": {"t_over_tau": s["t_over_tau"][::10].tolist(),
                            "runout": s["runout"][::10].tolist()}}
    print(json.dumps({k: v for k, v in row.items() if k != "runout_curve"}), flush=True)
    return row



def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--aspects", type=float, nargs="+", default=[0.5, 0.8, 2.0, 4.0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--state", default="dense")
    ap.add_argument("--shape", default="ngon")
    ap.add_argument("--tag", default=None)
    a = ap.parse_args(argv)
    tag = a.tag or f"n{a.n}"
    path = RESULTS / f"collapse_dry_{tag}.json"
    rows = []
    for aspect in a.aspects:
        for seed in a.seeds:
            rows.append(run(a.n, aspect, seed, a.state, a.shape))
            summary = {}
            for asp in a.aspects:
                mine = [r for r in rows if r["aspect_wanted"] == asp]
                if mine:
                    summary[str(asp)] = {"aspect": realisations([r["aspect"] for r in mine]),
                                         "runout": realisations([r["runout"] for r in mine]),
                                         "laws": {k: float(dry_runout(np.mean(
                                             [r["aspect"] for r in mine]), k))
                                             for k in DRY_LAWS}}
            out = {"benchmark": "collapse_dry", "machine": platform.platform(),
                   "cpus": os.cpu_count(), "python": platform.python_version(),
                   "summary": summary, "runs": rows}
            path.write_text(json.dumps(out, indent=1))  # after every run: partial results
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
