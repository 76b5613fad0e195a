"""A disk settling at Re ~350: steps without halvings, and what it costs.

A 2.5 mm disk (64-gon core), rho_p / rho_f = 1.5, in water-like fluid (nu = 1e-6 m^2/s),
released at rest at (1, 4) cm in a closed 2 cm x 6 cm channel, graded mesh, monolithic
coupling on the moving mesh, fixed steps dt = 2.5e-4 s, 0.3 s. Records the largest
particle Reynolds number ``rho_f |v| d / mu``, step halvings (``retries``), rejections,
remeshes, factorisations and Newton Jacobian refreshes, and the wall time by phase.

Writes ``benchmarks/results/settling_re350.json``.

Usage: ``python benchmarks/settling_re350.py [--t-end 0.3]``
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import time
from pathlib import Path

import numpy as np

from skfem_granular.scene import Scene
from skfem_granular.simulation import Simulation

ROOT = Path(__file__).resolve().parents[1]


def scene(t_end: float) -> Scene:
    return Scene.from_dict({
        "domain": {"box": [0.0, 0.0, 0.02, 0.06]},
        "fluid": {"density": 1000.0, "viscosity": 1e-3},
        "particles": [{"sides": 64, "radius": 1.25e-3, "center": [0.01, 0.04],
                       "density": 1500.0}],
        "mesh": {"kind": "graded"},
        "time": {"t_end": t_end, "dt": 2.5e-4}}, name="settling_re350")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--t-end", type=float, default=0.3)
    args = ap.parse_args()
    out = {"benchmark": "settling_re350", "machine": platform.platform(),
           "load_avg_start": os.getloadavg(),
           "commit": subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                                    capture_output=True, text=True).stdout.strip()}
    t0 = time.perf_counter()
    sim = Simulation(scene(args.t_end))
    res = sim.run(progress=False)
    h = res.history
    vmax = float(np.abs(h.vy[:, 0]).max())
    out.update(wall_s=time.perf_counter() - t0, steps=len(h), t_end=float(h.t[-1]),
               retries=sim.retries, rejections=sim.rejections, remeshes=sim.remeshes,
               re_max=1000.0 * vmax * 2.5e-3 / 1e-3, v_max=vmax, t_at_v_max=float(
                   h.t[int(np.argmax(np.abs(h.vy[:, 0])))]), y_end=float(h.y[-1, 0]),
               summary={k: res.summary.get(k) for k in (
                   "factorizations", "jacobian_refreshes", "remesh_reasons", "wall_time")},
               load_avg_end=os.getloadavg())
    out["wall_per_simulated_ms"] = out["wall_s"] / (1e3 * out["t_end"])
    (ROOT / "benchmarks/results/settling_re350.json").write_text(json.dumps(out, indent=1))
    print(json.dumps({k: out[k] for k in ("steps", "retries", "rejections", "remeshes",
                                          "re_max", "wall_s", "wall_per_simulated_ms")}))


if __name__ == "__main__":
    main()
