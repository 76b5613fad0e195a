"""The paper's single-particle runs on two source trees, interleaved in one run.

For refactors that must keep behaviour: runs the graded and the fine 1 ms runs
alternately with this checkout and with another checkout of the project (for
example ``git worktree add ../baseline <commit>``), each in a fresh process,
and compares ``v_y(1 ms)``, the wall time and the CPU time (``time.process_time``:
what the process itself computed, less disturbed by other load on the machine) of
``Simulation.run()`` (imports and process start excluded). Writes
``benchmarks/results/compare_trees.json``.

Usage: ``python benchmarks/compare_trees.py --baseline ../baseline [--repeat 5]``
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SNIPPET = r"""
import json, sys, time
from pathlib import Path
root, name = Path(sys.argv[1]), sys.argv[2]
from skfem_granular.scene import Scene
try:
    from skfem_granular.scene import bundled
    path = bundled(name)
except ImportError:  # trees from before the bundled scenes
    path = root / "scenes" / f"{name}.toml"
from skfem_granular.simulation import Simulation
from dataclasses import replace
scene = replace(Scene.from_toml(path), output_dir=None)
Simulation(scene).run(progress=False)  # warm-up: numba compilation, first-call set-up
t0, c0 = time.perf_counter(), time.process_time()
res = Simulation(scene).run(progress=False)
wall, cpu = time.perf_counter() - t0, time.process_time() - c0
print(json.dumps({"wall": wall, "cpu": cpu, "vy": repr(float(res.history.vy[-1, 0]))}))
"""


def run(tree: Path, name: str) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree))
    out = subprocess.run([sys.executable, "-c", SNIPPET, str(tree), name], env=env, cwd=tree,
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--baseline", required=True, help="another checkout of the project")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--out", default="compare_trees", help="results file name (no .json)")
    args = ap.parse_args()
    trees = {"baseline": Path(args.baseline).resolve(), "this": ROOT}
    rows = {}
    for name in ("single_particle", "single_particle_fine"):
        rec = {k: {"walls": [], "cpus": [], "vy": None} for k in trees}
        for _ in range(args.repeat):
            for label, tree in trees.items():  # interleaved: the machine's noise hits both
                r = run(tree, name)
                rec[label]["walls"].append(r["wall"])
                rec[label]["cpus"].append(r["cpu"])
                rec[label]["vy"] = r["vy"]
        for v in rec.values():
            v["wall_median_s"] = statistics.median(v["walls"])
            v["cpu_median_s"] = statistics.median(v["cpus"])
        b, t = float(rec["baseline"]["vy"]), float(rec["this"]["vy"])
        rec["vy_rel_diff"] = abs(t - b) / abs(b)
        rec["wall_ratio_this_over_baseline"] = (rec["this"]["wall_median_s"]
                                               / rec["baseline"]["wall_median_s"])
        rec["cpu_ratio_this_over_baseline"] = (rec["this"]["cpu_median_s"]
                                              / rec["baseline"]["cpu_median_s"])
        rows[name] = rec
        print(f"{name}: v_y(1 ms) {rec['baseline']['vy']} vs {rec['this']['vy']} "
              f"(rel diff {rec['vy_rel_diff']:.1e}); wall {rec['baseline']['wall_median_s']:.3f} "
              f"vs {rec['this']['wall_median_s']:.3f} s (ratio "
              f"{rec['wall_ratio_this_over_baseline']:.3f}); CPU "
              f"{rec['baseline']['cpu_median_s']:.3f} vs {rec['this']['cpu_median_s']:.3f} s "
              f"(ratio {rec['cpu_ratio_this_over_baseline']:.3f})")
    out = {"benchmark": "compare_trees", "machine": platform.platform(),
           "load_avg": os.getloadavg(), "baseline": str(trees["baseline"]),
           "repeat": args.repeat, "runs": rows}
    out["this_commit"] = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                                        capture_output=True, text=True).stdout.strip()
    path = ROOT / f"benchmarks/results/{args.out}.json"
    path.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
