"""The paper's Section 6 on this machine: graded vs fine mesh, and the step size.

Runs the bundled ``single_particle`` scene (graded) and its fine-mesh twin for
1 ms, whole runs including meshing and output, and a time-step convergence
series of the vertical velocity at 1 ms on the graded mesh. Writes
``benchmarks/results/single_particle.json`` and prints a markdown table.

Usage: ``python benchmarks/single_particle.py [--repeat 3]``
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from skfem_granular.scene import Scene, TimeSpec
from skfem_granular.simulation import Simulation

ROOT = Path(__file__).resolve().parents[1]


def run(scene, out=None):
    t0 = time.perf_counter()
    res = Simulation(scene, output_dir=out).run(progress=False)
    return time.perf_counter() - t0, res


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    scenes = {"graded": Scene.bundled("single_particle"),
              "fine": Scene.bundled("single_particle_fine")}
    rows = {}
    for name, sc in scenes.items():
        times, res = [], None
        for _ in range(args.repeat):
            with tempfile.TemporaryDirectory() as d:
                wall, res = run(sc, d)
            times.append(wall)
        h, s = res.history, res.summary
        rows[name] = {"wall_time_median_s": statistics.median(times), "wall_times_s": times,
                      "mesh": s["mesh"], "phases_s": s["wall_time"],
                      "vy_1ms": float(h.vy[-1, 0]), "vx_1ms": float(h.vx[-1, 0]),
                      "max_abs_vx": float(np.abs(h.vx).max()),
                      "drift_x": float(h.x[-1, 0] - 1.5e-3), "drop_y": float(h.y[-1, 0] - 5.5e-3),
                      "vy": h.vy[:, 0].tolist(), "t": h.t.tolist(),
                      "newton_mean": float(h.iterations.mean())}
    g, f = rows["graded"], rows["fine"]
    diff = float(np.abs(np.array(g["vy"]) - np.array(f["vy"])).max() / np.abs(f["vy"]).max())
    # step-size convergence of v_y(1 ms) on the graded mesh
    conv = []
    for dt in (4e-5, 2e-5, 1e-5, 5e-6, 2.5e-6):
        sc = replace(scenes["graded"], time=TimeSpec(t_end=1e-3, dt=dt))
        wall, res = run(sc)
        conv.append({"dt": dt, "vy_1ms": float(res.history.vy[-1, 0]), "wall_time_s": wall})
    ref = conv[-1]["vy_1ms"]
    for c in conv:
        c["rel_diff_to_finest"] = abs(c["vy_1ms"] / ref - 1)
    out = {"benchmark": "single_particle", "machine": platform.platform(), "cpus": 2,
           "graded": g, "fine": f, "max_rel_diff_vy_curves": diff,
           "time_ratio_fine_over_graded": f["wall_time_median_s"] / g["wall_time_median_s"],
           "dt_convergence_graded": conv,
           "paper": {"fine_s": 7437.8, "graded_s": 1317.0, "ratio": 7437.8 / 1317.0}}
    path = ROOT / "benchmarks/results/single_particle.json"
    path.write_text(json.dumps(out, indent=1))
    print("| mesh | vertices | P2 nodes | DOFs | v_y(1 ms) | max abs v_x | x drift | wall time |")
    print("|---|---|---|---|---|---|---|---|")
    for name, r in rows.items():
        m = r["mesh"]
        print(f"| {name} | {m['vertices']} | {m['p2_nodes']} | {m['dofs']} | "
              f"{r['vy_1ms']:.5e} m/s | {r['max_abs_vx']:.1e} m/s | {r['drift_x']:.1e} m | "
              f"{r['wall_time_median_s']:.2f} s |")
    print(f"\nv_y curves differ by at most {100 * diff:.2f} %; fine/graded wall time "
          f"{out['time_ratio_fine_over_graded']:.1f}x (paper 5.6x)")
    print("\n| dt | v_y(1 ms) | rel. diff to dt = 2.5e-6 | wall |\n|---|---|---|---|")
    for c in conv:
        print(f"| {c['dt']:.1e} | {c['vy_1ms']:.6e} | {c['rel_diff_to_finest']:.1e} | "
              f"{c['wall_time_s']:.2f} s |")


if __name__ == "__main__":
    main()
