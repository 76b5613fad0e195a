"""Where a granular run spends its time, step by step: free fall against contacts.

Runs a bundled scene (default the paper's collapse) and records, for every
accepted step, its wall and CPU time, the mesh size (DOFs), the number of open
contacts, the step kind (BDF2, or backward Euler at contacts), the corrector's
iterations, and whether the step remeshed, refactorised the BDF2-Stokes operator
or refreshed the Newton Jacobian (with the phase times of that step). The JSON
(``benchmarks/results/<tag>.json``) holds the rows and a summary:

- per window of steps: time per step (mean and median), per DOF, contacts, events;
- *plain* steps (no remesh, factorisation or refresh) with and without contacts,
  per step and per 1000 DOFs, so that the contact phase's own cost is told apart
  from the mesh's growth and from the events that interrupt it;
- the share of the run's time spent in steps with each kind of event.

Usage::

    python benchmarks/contact_phase.py                         # collapse to 0.16 s
    python benchmarks/contact_phase.py --t-end 0.08 --tag contact_phase_short

Compare two codes with the ratios of one interleaved run (the machines are noisy):
run this script from both trees one after the other, several times, and compare
the ``cpu_s`` totals of pairs.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from skfem_granular.scene import Scene
from skfem_granular.simulation import Simulation

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks/results"


def record(sim, t_end: float | None, progress: bool) -> tuple[list[dict], float, float]:
    """Run ``sim`` and return one row per accepted step, wall and CPU seconds in total."""
    st = sim.stepper
    rows = []
    before = dict(st.factor_counts, remeshes=st.remeshes, euler=st.euler_steps)
    phases = dict(st.collect_timings())
    wall0 = tick = time.perf_counter()
    cpu0 = cpu = time.process_time()
    for t, step in sim.evolve(progress=progress):
        now, cpu_now = time.perf_counter(), time.process_time()
        counts = dict(st.factor_counts, remeshes=st.remeshes, euler=st.euler_steps)
        timings = dict(st.collect_timings())
        rows.append({
            "t": float(t), "dt": float(step.dt), "wall_s": now - tick, "cpu_s": cpu_now - cpu,
            "dofs": int(st.space.N), "contacts": _contacts(sim.dem),
            "iterations": int(step.iterations),
            "euler": bool(st.state.euler),
            **{k: counts[k] - before[k] for k in counts},
            "phases_s": {k: v - phases.get(k, 0.0) for k, v in timings.items()},
        })
        before, phases, tick, cpu = counts, timings, now, cpu_now
        if t_end is not None and t >= t_end - 1e-12:
            break
    return rows, time.perf_counter() - wall0, time.process_time() - cpu0


def _contacts(dem) -> int:
    """Open contacts (grain-grain and grain-wall pairs) after the last DEM substep."""
    return 0 if dem.contacts is None else int(dem.contacts.i.size)


def _stats(rows: list[dict]) -> dict:
    if not rows:
        return {"steps": 0}
    w = np.array([r["wall_s"] for r in rows])
    c = np.array([r["cpu_s"] for r in rows])
    d = np.array([r["dofs"] for r in rows], dtype=float)
    return {"steps": len(rows), "wall_ms_mean": 1e3 * w.mean(),
            "wall_ms_median": 1e3 * np.median(w),
            "cpu_ms_mean": 1e3 * c.mean(), "cpu_ms_median": 1e3 * np.median(c),
            "cpu_ms_per_kdof_median": 1e6 * np.median(c / d),
            "dofs_mean": float(d.mean()),
            "contacts_mean": float(np.mean([r["contacts"] for r in rows])),
            "iterations_mean": float(np.mean([r["iterations"] for r in rows])),
            **{k: int(sum(r[k] for r in rows))
               for k in ("remeshes", "factorizations", "jacobian_refreshes")},
            "euler_steps": int(sum(r["euler"] for r in rows))}


def summarise(rows: list[dict], windows: int = 5) -> dict:
    """Per-window statistics, plain steps with and without contacts, event shares."""
    n = len(rows)
    edges = np.linspace(0, n, windows + 1).astype(int)
    per_window = [{"steps": [int(a), int(b)], "t": [rows[a]["t"], rows[b - 1]["t"]],
                   **_stats(rows[a:b])}
                  for a, b in zip(edges[:-1], edges[1:], strict=True) if b > a]

    def eventful(r):
        return r["remeshes"] or r["factorizations"] or r["jacobian_refreshes"]

    plain = [r for r in rows if not eventful(r)]
    cpu_total = sum(r["cpu_s"] for r in rows)
    shares = {}
    for k in ("remeshes", "factorizations", "jacobian_refreshes"):
        shares[k] = sum(r["cpu_s"] for r in rows if r[k]) / cpu_total
    shares["plain"] = sum(r["cpu_s"] for r in plain) / cpu_total
    return {"windows": per_window,
            "plain_without_contacts": _stats([r for r in plain if r["contacts"] == 0]),
            "plain_with_contacts": _stats([r for r in plain if r["contacts"] > 0]),
            "contact_steps": _stats([r for r in rows if r["contacts"] > 0]),
            "free_steps": _stats([r for r in rows if r["contacts"] == 0]),
            "cpu_share_of_steps_with": shares}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="collapse")
    ap.add_argument("--t-end", type=float, default=None, help="default: the scene's")
    ap.add_argument("--tag", default="contact_phase")
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args()
    sc = Scene.bundled(args.scene)
    if args.t_end is not None:
        sc = replace(sc, time=replace(sc.time, t_end=args.t_end))
    load0 = list(os.getloadavg())
    sim = Simulation(sc, output_dir=ROOT / "out" / args.tag)
    rows, wall, cpu = record(sim, args.t_end, progress=not args.quiet)
    try:
        commit = subprocess.run(["git", "-C", str(ROOT), "log", "-1", "--format=%h"],
                                capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = None
    pos = sim.dem.positions
    out = {"benchmark": "contact_phase", "scene": args.scene, "commit": commit,
           "particles": sim.dem.n, "t_end": rows[-1]["t"] if rows else 0.0,
           "wall_s": wall, "cpu_s": cpu, "phases_s": dict(sim.stepper.collect_timings()),
           "loadavg_start": load0, "loadavg_end": list(os.getloadavg()),
           "final": {"mean_y": float(pos[1].mean()), "spread_x": float(pos[0].std())},
           "summary": summarise(rows), "rows": rows}
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"{args.tag}.json").write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps({k: v for k, v in out.items() if k != "rows"}, indent=1))


if __name__ == "__main__":
    main()
