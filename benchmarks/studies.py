"""Accuracy against cost: run both studies and publish their tables and figures.

Runs ``skfem_granular.studies.run_study`` for ``single-particle`` and ``faxen``
(resuming from ``out/study_<name>[_smoke]/`` when runs are already there),
times each study, and copies the tables to ``benchmarks/results/study_<name>.{md,csv}``
and the figures to ``docs/figures/study_<name>_{pareto,convergence,fig2}.png``
(``--smoke``: ``benchmarks/results/study_smoke.json`` with the timings only).

Usage: ``python benchmarks/studies.py [--smoke] [--workers 2] [--fresh]``
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import time
from pathlib import Path

from skfem_granular.studies import STUDIES, orders, run_study

ROOT = Path(__file__).resolve().parents[1]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--smoke", action="store_true")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--fresh", action="store_true", help="delete earlier runs first")
    args = ap.parse_args()
    report = {"machine": platform.platform(), "cpus": os.cpu_count(), "workers": args.workers,
              "smoke": args.smoke, "load_average_before": os.getloadavg(), "studies": {}}
    for study in STUDIES:
        name = study.replace("-", "_")
        out = ROOT / "out" / f"study_{name}{'_smoke' if args.smoke else ''}"
        if args.fresh:
            shutil.rmtree(out, ignore_errors=True)
        t0 = time.perf_counter()
        res = run_study(study, out, smoke=args.smoke, workers=args.workers)
        wall = time.perf_counter() - t0
        report["studies"][study] = {
            "wall_time_s": round(wall, 1), "runs": len(res.rows), "computed": len(res.computed),
            "failed": res.failed, "orders_h_equivalent": orders(res.rows),
            "sum_of_run_wall_times_s": round(sum(r["wall_time"] for r in res.rows), 1)}
        print(f"{study}: {len(res.rows)} runs ({len(res.computed)} computed) in {wall:.1f} s")
        if not args.smoke:
            res_dir = ROOT / "benchmarks" / "results"
            for ext in ("md", "csv"):
                shutil.copy(out / f"table.{ext}", res_dir / f"study_{name}.{ext}")
            for fig in ("pareto", "convergence", "fig2"):
                shutil.copy(out / f"{fig}.png", ROOT / "docs/figures" / f"study_{name}_{fig}.png")
    report["load_average_after"] = os.getloadavg()
    path = ROOT / "benchmarks/results" / f"study_{'smoke' if args.smoke else 'full'}.json"
    if any(s["computed"] for s in report["studies"].values()):
        path.write_text(json.dumps(report, indent=2) + "\n")
        print(f"wrote {path}")
    else:
        print(f"all runs resumed: timings in {path} kept")


if __name__ == "__main__":
    main()
