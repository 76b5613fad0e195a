"""What the coupled corrector's tolerance costs and buys in dense granular flow.

The monolithic coupling iterates each step on a held factorisation until its update
is below ``newton_tol`` (scene key ``[coupling] newton_tol``) of the velocity scale;
in a dense immersed column the held Jacobian goes stale within a step or two
(``chord_drift.py``), so a tight tolerance buys its last digits with Jacobian
refreshes. Two measurements, each run a process of its own, the tolerances
interleaved:

``column``
    The contact-dominated column of :mod:`scaling_contact` (dense, 12-gon near-disks,
    core ratio 0.9, steps of 0.2 ms) released in water for ``--steps`` steps at each
    tolerance: iterations, Jacobian refreshes, CPU time, and the grains' velocities
    after every step. With ``--reference T`` a run at the tight tolerance ``T`` is the
    reference, and one more run at ``T`` with half the step (``--no-half`` skips it)
    measures the time step's own error at the same times: the tolerance's error and the
    time step's, each the largest velocity difference over the grains, over the
    largest grain speed of the reference at that step.
``collapse``
    The paper's collapse (bundled ``collapse``, 25 hexagons) with the grid seeded 1, 2,
    3, to ``--t-end``: CPU time, iterations, refreshes, and the grains' mean height and
    horizontal spread at 0.05 / 0.1 / 0.16 s as mean and spread over the seeds.

Usage::

    python benchmarks/corrector_tolerance.py column --n 100 --steps 30 --reference 1e-12
    python benchmarks/corrector_tolerance.py column --n 1000 --steps 12 --tol 1e-8 1e-6
    python benchmarks/corrector_tolerance.py collapse --tol 1e-8 1e-6

Writes ``benchmarks/results/corrector_tolerance_<what>[_n<N>].json``.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks/results"
TOLERANCES = (1e-8, 1e-7, 1e-6, 1e-5)


def _counts(sim) -> dict:
    st = sim.stepper
    return {"dofs": int(st.space.N), "remeshes": int(st.remeshes),
            **{k: int(v) for k, v in st.factor_counts.items()}}


def column_child(n: int, steps: int, tol: float, dt_factor: float) -> dict:
    """The released column at ``tol``, velocities after every step of the coarse clock."""
    from scaling_contact import CORE_RATIO, DT, packing

    from skfem_granular.collapse import column_scene
    from skfem_granular.simulation import Simulation

    dt = DT * dt_factor
    scene = replace(column_scene(packing(n), fluid=True, core_ratio=CORE_RATIO,
                                 t_end=steps * DT, dt=dt, name=f"tolerance_{n}"),
                    newton_tol=tol)
    cpu0 = time.process_time()
    sim = Simulation(scene)
    cpu_start = time.process_time() - cpu0
    its, V = [], []
    every = round(1.0 / dt_factor)
    for k, (_t, step) in enumerate(sim.evolve(), start=1):
        its.append(int(step.iterations))
        if k % every == 0:
            d = sim.dem
            V.append(np.vstack([d.velocities, d.angular_velocities[None]]).tolist())
    return {"grains": n, "tol": tol, "dt": dt, "steps": len(its), "iterations": its,
            "iterations_total": sum(its), "cpu_s": time.process_time() - cpu0,
            "cpu_start_s": cpu_start, "phases_s": sim.result.summary.get("wall_time"),
            "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
            **_counts(sim), "velocities": V}


def collapse_child(tol: float, seed: int, t_end: float) -> dict:
    """The bundled collapse, its grid seeded ``seed``, at ``tol``."""
    from gap_lining import MARKS, seeded_collapse

    from skfem_granular.simulation import Simulation

    sc = seeded_collapse(seed)
    sc = replace(sc, time=replace(sc.time, t_end=t_end), newton_tol=tol, output_dir=None)
    cpu0, wall0 = time.process_time(), time.perf_counter()
    sim = Simulation(sc)
    its, marks = [], {}
    for t, step in sim.evolve():
        its.append(int(step.iterations))
        for m in MARKS:
            if f"{m:g}" not in marks and t >= m - 1e-9:
                q = sim.dem.positions
                marks[f"{m:g}"] = {"mean_y": float(q[1].mean()), "spread_x": float(q[0].std())}
    return {"tol": tol, "seed": seed, "t_end": t_end, "cpu_s": time.process_time() - cpu0,
            "wall_s": time.perf_counter() - wall0, "steps": len(its),
            "iterations_total": sum(its), "euler_steps": int(sim.euler_steps),
            **_counts(sim), "marks": marks}


def run_child(*args) -> dict:
    """This script's ``--child`` run of ``args`` in a fresh interpreter."""
    from child_process import run_child as run

    return run(__file__, *args)


def velocity_errors(run: dict, ref: dict) -> list:
    """Per step: the largest grain velocity difference to ``ref`` over ``ref``'s largest
    grain speed then (translational velocities only)."""
    V, R = np.asarray(run["velocities"])[:, :2], np.asarray(ref["velocities"])[:, :2]
    k = min(len(V), len(R))
    scale = np.abs(R[:k]).max(axis=(1, 2))
    return (np.abs(V[:k] - R[:k]).max(axis=(1, 2)) / scale).tolist()


def column(a) -> dict:
    from scaling_contact import DT

    runs = []
    tols = list(a.tol)
    plan = [(t, 1.0) for t in tols]
    if a.reference is not None:
        plan = [(a.reference, 1.0)] + plan + ([] if a.no_half else [(a.reference, 0.5)])
    for tol, f in plan:
        runs.append(run_child("column", a.n, a.steps, tol, f))
        print(json.dumps({k: v for k, v in runs[-1].items() if k != "velocities"}), flush=True)
    if a.reference is not None:
        ref = runs[0]
        for r in runs[1:]:
            r["velocity_error"] = velocity_errors(r, ref)
            r["velocity_error_max"] = max(r["velocity_error"])
    for r in runs:
        r.pop("velocities")
        r["cpu_per_ms"] = (r["cpu_s"] - r["cpu_start_s"]) / (a.steps * DT * 1e3)
    return {"benchmark": "corrector_tolerance_column", "grains": a.n, "steps": a.steps,
            "reference": a.reference, "runs": runs}


def collapse(a) -> dict:
    from skfem_granular.collapse import realisations

    runs = []
    for seed in a.seeds:  # interleaved: every tolerance once per seed
        for tol in a.tol:
            runs.append(run_child("collapse", tol, seed, a.t_end))
            print(json.dumps({k: v for k, v in runs[-1].items() if k != "marks"}), flush=True)
    summary = []
    for tol in a.tol:
        rs = [r for r in runs if r["tol"] == tol]
        row = {"tol": tol, "seeds": [r["seed"] for r in rs]}
        for key in ("cpu_s", "steps", "iterations_total", "jacobian_refreshes",
                    "factorizations", "remeshes", "euler_steps"):
            row[key] = realisations([r[key] for r in rs])
        for m in rs[0]["marks"]:
            for q in ("mean_y", "spread_x"):
                row[f"{q}@{m}"] = realisations([r["marks"][m][q] for r in rs])
        summary.append(row)
    base = [r for r in runs if r["tol"] == a.tol[0]]
    for tol in a.tol[1:]:  # CPU ratio seed by seed against the first tolerance
        pairs = zip([r for r in runs if r["tol"] == tol], base, strict=True)
        ratios = [r["cpu_s"] / b["cpu_s"] for r, b in pairs]
        next(s for s in summary if s["tol"] == tol)["cpu_ratio"] = realisations(ratios)
    return {"benchmark": "corrector_tolerance_collapse", "t_end": a.t_end, "runs": runs,
            "summary": summary}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", nargs="?", choices=("column", "collapse"))
    ap.add_argument("--n", type=int, default=100)
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--tol", type=float, nargs="+", default=list(TOLERANCES))
    ap.add_argument("--reference", type=float, default=None)
    ap.add_argument("--no-half", action="store_true")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--t-end", type=float, default=0.16)
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        kind, *args = a.child
        if kind == "column":
            rec = column_child(int(args[0]), int(args[1]), float(args[2]), float(args[3]))
        else:
            rec = collapse_child(float(args[0]), int(args[1]), float(args[2]))
        print(json.dumps(rec))
        return
    load0 = list(os.getloadavg())
    data = column(a) if a.what == "column" else collapse(a)
    data.update(cpus=os.cpu_count(), loadavg_start=load0, loadavg_end=list(os.getloadavg()))
    out = a.out or RESULTS / (f"corrector_tolerance_{a.what}"
                              + (f"_n{a.n}" if a.what == "column" else "") + ".json")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(data, indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    main()
