"""Moving mesh (ALE) against the fixed mesh: cost, and independence of the remesh trigger.

1. The paper's single particle, graded and fine, 1 ms: wall time and CPU time of
   ``Simulation.run()`` and ``v_y(1 ms)`` for both schemes, interleaved (medians of
   ``--repeat``).
2. A disk settling in a closed 2 cm x 6 cm channel (d = 2.5 mm, 32-gon, rho_p = 1250,
   rho_f = 1000 kg/m^3, nu = 1e-5 m^2/s, from (1, 4) cm, dt = 5e-4 s, graded mesh) for
   ``--t-settle`` seconds: the largest settling speed and the final height for each
   scheme at its default remesh threshold and at a 4x stricter one (fixed:
   remesh_fraction 0.25 -> 0.0625; ALE: remesh_travel 1 -> 0.25 radii), with remeshes
   and wall time.

Writes ``benchmarks/results/ale.json`` and prints markdown tables.

Usage: ``python benchmarks/ale.py [--repeat 5] [--t-settle 0.7] [--skip-settling]
[--skip-paper] [--tag ale]`` (results in ``benchmarks/results/<tag>.json``)
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from skfem_granular.scene import Scene
from skfem_granular.simulation import Simulation

ROOT = Path(__file__).resolve().parents[1]


def timed_run(scene, cpu: bool = False):
    """Wall time (or, with ``cpu``, the process's CPU time) of one run, and its result."""
    clock = time.process_time if cpu else time.perf_counter
    t0 = clock()
    res = Simulation(scene).run(progress=False)
    return clock() - t0, res


def settling_scene(t_end: float) -> Scene:
    return Scene.from_dict({
        "domain": {"box": [0.0, 0.0, 0.02, 0.06]},
        "fluid": {"density": 1000.0, "viscosity": 0.01},
        "particles": [{"sides": 32, "radius": 1.25e-3, "center": [0.01, 0.04],
                       "density": 1250.0}],
        "mesh": {"kind": "graded"},
        "time": {"t_end": t_end, "dt": 5e-4}}, name="settling_disk")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--t-settle", type=float, default=0.7)
    ap.add_argument("--skip-settling", action="store_true")
    ap.add_argument("--skip-paper", action="store_true")
    ap.add_argument("--tag", default="ale")
    args = ap.parse_args()
    out = {"benchmark": "ale", "machine": platform.platform(), "load_avg_start": os.getloadavg(),
           "commit": subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                                    capture_output=True, text=True).stdout.strip()}
    paper = {}
    for name in () if args.skip_paper else ("single_particle", "single_particle_fine"):
        base = replace(Scene.bundled(name), output_dir=None)
        rec = {m: {"walls": [], "cpus": []} for m in ("fixed", "ale")}
        for m in rec:  # warm-up (numba, first-call set-up)
            timed_run(replace(base, mesh_motion=m))
        for _ in range(args.repeat):
            for m in rec:
                wall, res = timed_run(replace(base, mesh_motion=m))
                rec[m]["walls"].append(wall)
                rec[m]["cpus"].append(timed_run(replace(base, mesh_motion=m), cpu=True)[0])
                rec[m]["vy_1ms"] = float(res.history.vy[-1, 0])
                rec[m]["iterations_mean"] = float(res.history.iterations.mean())
        for v in rec.values():
            v["wall_median_s"] = statistics.median(v["walls"])
            v["cpu_median_s"] = statistics.median(v["cpus"])
        rec["wall_ratio_ale_over_fixed"] = (rec["ale"]["wall_median_s"]
                                            / rec["fixed"]["wall_median_s"])
        rec["cpu_ratio_ale_over_fixed"] = (rec["ale"]["cpu_median_s"]
                                           / rec["fixed"]["cpu_median_s"])
        rec["vy_rel_diff"] = abs(rec["ale"]["vy_1ms"] / rec["fixed"]["vy_1ms"] - 1)
        paper[name] = rec
    out["single_particle"] = paper
    print("| run | fixed wall | ALE wall | ratio | CPU ratio | v_y(1 ms) fixed | v_y(1 ms) ALE |")
    print("|---|---|---|---|---|---|---|")
    for name, r in paper.items():
        print(f"| {name} | {r['fixed']['wall_median_s']:.3f} s | {r['ale']['wall_median_s']:.3f} s"
              f" | {r['wall_ratio_ale_over_fixed']:.2f} | {r['cpu_ratio_ale_over_fixed']:.2f} | "
              f"{r['fixed']['vy_1ms']:.6e} | {r['ale']['vy_1ms']:.6e} |")
    if not args.skip_settling:
        sc = settling_scene(args.t_settle)
        cases = {"fixed": {"mesh_motion": "fixed", "remesh_fraction": 0.25},
                 "fixed_strict": {"mesh_motion": "fixed", "remesh_fraction": 0.0625},
                 "ale": {"mesh_motion": "ale", "remesh_travel": 1.0},
                 "ale_strict": {"mesh_motion": "ale", "remesh_travel": 0.25}}
        rows = {}
        for label, kw in cases.items():
            wall, res = timed_run(replace(sc, **kw))
            h = res.history
            rows[label] = {"wall_s": wall, "max_speed": float(np.abs(h.vy[:, 0]).max()),
                           "final_height": float(h.y[-1, 0]), "remeshes": res.summary["remeshes"],
                           "retries": res.summary["retries"], "steps": len(h)}
            print(label, rows[label], flush=True)
        for m in ("fixed", "ale"):
            a, b = rows[m], rows[m + "_strict"]
            rows[m + "_spread"] = {"max_speed_rel": abs(b["max_speed"] / a["max_speed"] - 1),
                                   "final_height_rel": abs(b["final_height"] / a["final_height"]
                                                           - 1)}
        out["settling"] = {"t_end": args.t_settle, "runs": rows}
        print("| scheme | threshold | max speed | final height | remeshes | wall |")
        print("|---|---|---|---|---|---|")
        for label, r in rows.items():
            if "spread" in label:
                continue
            print(f"| {label} | {cases[label]} | {r['max_speed']:.5f} m/s | "
                  f"{r['final_height'] * 1e3:.3f} mm | {r['remeshes']} | {r['wall_s']:.1f} s |")
    out["load_avg_end"] = os.getloadavg()
    path = ROOT / f"benchmarks/results/{args.tag}.json"
    path.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
