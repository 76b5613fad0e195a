"""Loose against dense, dry against immersed: the collapse matrix over core ratios and seeds.

Usage::

    python benchmarks/collapse_matrix.py --smoke            # 30 grains, 4 ms: the pipeline
    python benchmarks/collapse_matrix.py                    # 200 grains, a = 0.8, 8 tau_c
    python benchmarks/collapse_matrix.py --cores 0.8 --seeds 0 --media immersed
    python benchmarks/collapse_matrix.py --n 1000 --cores 0.9 --seeds 0 --to-rest --tag n1000

Every run is a column of ``--n`` grains (:func:`skfem_granular.packing.prepare_column`,
12-gon near-disks, d_max / d_min = 1.8, aspect 0.8; the packings are kept in
``results/packings/``) released behind its gate (:func:`skfem_granular.collapse.column_scene`)
dry or in water, the immersed runs at each core ratio (the dry ones need none). A run
writes its output folder ``out/collapse_matrix/<run>`` with a checkpoint every
``--checkpoint-every`` steps: a run cut off is continued where its checkpoint stands the
next time this script is started (:meth:`Simulation.resume`), a finished one is read
back, not run again. Per run the JSON records the cost (CPU, wall, DOFs, steps) and the
run-out series (:func:`skfem_granular.collapse.collapse_series`); ``cpu_s`` and ``wall_s``
are summed over the processes that ran it (kept in its folder's ``cost.json``); per set-up
(state, medium, core ratio) the final run-out (the deposit's mass front,
:func:`skfem_granular.collapse.mass_front`), the largest front Froude number and the
time to 90 % of the final run-out as mean and spread over the seeds
(:func:`skfem_granular.collapse.realisations`). Results:
``benchmarks/results/collapse_matrix_<tag>.json``.

With ``--to-rest`` a run ends when the grains' kinetic energy has fallen below
``--stop-ratio`` of its peak after ``--t-min`` (in tau_c), or at ``--t-max``; its folder
then keeps ``rest.json`` (when, the energy ratio, whether at rest) and its record says
``at_rest``. The records also carry the run's phase times (``phases_s``, summed over its
processes), factorisations, Jacobian refreshes, the largest mesh and the peak memory.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks/results"
ASPECT = 0.8


def packing(n: int, state: str, seed: int, t_max: float = 3.0):
    """The column (prepared once, then read from ``results/packings/``; ``t_max``: the
    deposition's time limit, :func:`~skfem_granular.packing.prepare_column`)."""
    from skfem_granular.packing import load_packing, prepare_column

    path = RESULTS / "packings" / f"{state}_a{ASPECT:g}_n{n}_seed{seed}.npz"
    if path.exists():
        return load_packing(path)
    pk = prepare_column(n, ASPECT, state, seed=seed, t_max=t_max)
    path.parent.mkdir(parents=True, exist_ok=True)
    pk.save(path)
    return pk


def completed(folder: Path) -> bool:
    """Whether the run in ``folder`` reached its end (its summary says so, or it came to
    rest: ``rest.json``)."""
    if (folder / "rest.json").exists():
        return True
    path = folder / "summary.json"
    return path.exists() and json.loads(path.read_text()).get("status") == "completed"


def energy_peak(pk, folder: Path) -> float:
    """The largest kinetic energy in the run's history so far (0 for a new run)."""
    from skfem_granular.collapse import history_columns, kinetic_energies, masses

    path = folder / "history.csv"
    if not path.exists():
        return 0.0
    c = history_columns(path)
    m, J = masses(pk)
    return max((sum(kinetic_energies(m, J, (vx, vy), w))
                for vx, vy, w in zip(c["vx"], c["vy"], c["omega"], strict=True)), default=0.0)


def simulation(pk, medium: str, core: float, t_end: float, folder: Path, every: int):
    """A new run into ``folder``, or the run continued from its checkpoint there."""
    from skfem_granular.collapse import column_scene
    from skfem_granular.simulation import Simulation

    if (folder / "checkpoint.npz").exists():
        return Simulation.resume(folder)
    scene = column_scene(pk, fluid=medium == "immersed", core_ratio=core, t_end=t_end,
                         name=folder.name, output_dir=str(folder), vtu_every=250)
    return Simulation(replace(scene, checkpoint_every=every), overwrite=True)


def measure(pk, folder: Path, domain) -> dict:
    """Run-out series and the final deposit of a finished run, from its files."""
    from skfem_granular.collapse import (
        collapse_series,
        grain_outlines,
        history_columns,
        local_outlines,
        mass_front,
    )

    cols = history_columns(folder / "history.csv")
    s = collapse_series(cols, pk, domain)
    local, _ = local_outlines(pk)
    final = grain_outlines(local, cols["x"][-1], cols["y"][-1], cols["angle"][-1])
    L_end = mass_front([P - np.array([[domain[0]], [domain[1]]]) for P in final])
    r_end = (L_end - pk.width) / pk.width
    reach = s["runout"] >= 0.9 * r_end
    return {"final_runout_mass_front": float(r_end),
            "final_runout_gap_front": float(s["runout"][-1]),
            "froude_max": float(np.nanmax(s["froude"])),
            "t90_over_tau": float(s["t_over_tau"][np.argmax(reach)]) if reach.any() else None,
            "series": {k: np.asarray(s[k]).tolist()
                       for k in ("t_over_tau", "runout", "E_x", "E_y", "froude")}}


def add_cost(folder: Path, cpu: float, wall: float, dofs: list, phases: dict) -> dict:
    """Add this process's share to the run's ``cost.json`` and return the totals."""
    import resource

    path = folder / "cost.json"
    c = json.loads(path.read_text()) if path.exists() else {
        "cpu_s": 0.0, "wall_s": 0.0, "processes": 0, "dofs_sum": 0, "dofs_steps": 0}
    c.setdefault("phases_s", {})
    if dofs:  # a process that stepped (not one that only read a finished run back)
        c["cpu_s"] += cpu
        c["wall_s"] += wall
        c["processes"] += 1
        c["dofs_sum"] += int(np.sum(dofs))
        c["dofs_steps"] += len(dofs)
        c["dofs_max"] = max(c.get("dofs_max", 0), int(np.max(dofs)))
        c["peak_mb"] = max(c.get("peak_mb", 0.0),
                           resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
        for k, v in phases.items():
            c["phases_s"][k] = c["phases_s"].get(k, 0.0) + float(v)
        path.write_text(json.dumps(c) + "\n")
    return {"cpu_s": c["cpu_s"], "wall_s": c["wall_s"], "processes": c["processes"],
            "dofs_mean": c["dofs_sum"] / c["dofs_steps"] if c["dofs_sum"] else None,
            "dofs_max": c.get("dofs_max"), "peak_mb": c.get("peak_mb"),
            "phases_s": c["phases_s"]}


def one(n, state, medium, core, seed, tau_end, root: Path, every: int,
        rest: dict | None = None, packing_t_max: float = 3.0) -> dict | None:
    """Run (or continue, or read back) one run of the matrix and measure it; None if it did
    not reach its end (stopped by a signal: its checkpoint is kept; or failed): nothing is
    recorded then. ``rest``: ``{"stop_ratio", "t_min"}`` (t_min in tau_c) to end the run
    when the kinetic energy falls below ``stop_ratio`` of its peak after ``t_min``."""
    from skfem_granular.collapse import time_scale

    pk = packing(n, state, seed, packing_t_max)
    tag = f"{state}_{medium}" + (f"_core{core:g}" if medium == "immersed" else "") + f"_s{seed}"
    folder = root / tag
    c0, w0, dofs, phases = time.process_time(), time.perf_counter(), [], {}
    tau = time_scale(pk)
    if completed(folder):
        from skfem_granular.collapse import column_scene

        domain = column_scene(pk, fluid=False).domain
    else:
        sim = simulation(pk, medium, core, tau_end * tau, folder, every)
        domain = sim.scene.domain
        peak = energy_peak(pk, folder) if rest else 0.0
        steps = sim.evolve(progress=False)
        for t, _ in steps:
            dofs.append(int(sim.space.N) if medium == "immersed" else 0)
            if rest:
                E = sim.dem.kinetic_energy()
                peak = max(peak, E)
                if t > rest["t_min"] * tau and E < rest["stop_ratio"] * peak:
                    steps.close()  # at rest: the files are completed by the generator
                    (folder / "rest.json").write_text(json.dumps(
                        {"t": t, "t_over_tau": t / tau, "energy_ratio": E / peak,
                         "stop_ratio": rest["stop_ratio"], "at_rest": True,
                         "steps": sim.steps_done}) + "\n")
                    break
        phases = dict(sim.result.summary.get("wall_time", {})) if sim.result else {}
    summary = json.loads((folder / "summary.json").read_text())
    cost = add_cost(folder, time.process_time() - c0, time.perf_counter() - w0, dofs, phases)
    rest_rec = json.loads((folder / "rest.json").read_text()) if (
        folder / "rest.json").exists() else None
    if rest_rec is not None:
        summary["status"] = "completed"  # at rest before t_max: the run's end
    if summary.get("status") != "completed":  # not a result: nothing is recorded
        why = (f"failed: {summary.get('failed')}" if summary.get("status") == "failed" else
               f"stopped by {summary.get('stopped_by')}; start again to continue")
        print(f"{tag}: {summary.get('status')} at step {summary.get('steps')} ({why})",
              flush=True)
        return None
    rec = {"run": tag, "state": state, "medium": medium, "core_ratio": core, "seed": seed,
           "grains": pk.n, "solid_fraction": pk.solid_fraction, "tau_c": time_scale(pk),
           **cost, "steps": summary.get("steps"), "remeshes": summary.get("remeshes"),
           "factorizations": summary.get("factorizations"),
           "jacobian_refreshes": summary.get("jacobian_refreshes"),
           "t_end_over_tau": summary.get("t_end", 0.0) / tau}
    if rest:
        rec["at_rest"] = rest_rec is not None
        if rest_rec is not None:
            rec["energy_ratio"] = rest_rec["energy_ratio"]
    rec.update(measure(pk, folder, domain))
    return rec


def summarise(runs: list) -> list:
    from skfem_granular.collapse import realisations

    groups: dict = {}
    for r in runs:
        groups.setdefault((r["state"], r["medium"], r["core_ratio"]), []).append(r)
    out = []
    for (state, medium, core), rs in sorted(groups.items(), key=lambda kv: str(kv[0])):
        row = {"state": state, "medium": medium, "core_ratio": core,
               "seeds": [r["seed"] for r in rs]}
        for key in ("final_runout_mass_front", "froude_max", "t90_over_tau", "cpu_s",
                    "solid_fraction"):
            vals = [r[key] for r in rs if r[key] is not None]
            row[key] = realisations(vals) if vals else None
        out.append(row)
    return out


def earlier_runs(out: Path) -> list:
    """The runs already in the results file (kept when their output folders are gone)."""
    return json.loads(out.read_text())["runs"] if out.exists() else []


def record(out: Path, rec: dict) -> None:
    """Put ``rec`` into the results file in place of an earlier record of the same run.

    The file is read, updated and written under an exclusive lock, so that several
    processes working through different runs of one matrix (``--states dense`` in one,
    ``--states loose`` in another) keep each other's records.
    """
    import fcntl

    lock_path = ROOT / "out" / f"{out.stem}.lock"
    lock_path.parent.mkdir(parents=True, exist_ok=True)
    with open(lock_path, "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        runs = [r for r in earlier_runs(out) if r["run"] != rec["run"]] + [rec]
        out.write_text(json.dumps({"benchmark": "collapse_matrix", "aspect": ASPECT,
                                   "cpus": os.cpu_count(), "runs": runs,
                                   "summary": summarise(runs)}, indent=1) + "\n")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--states", nargs="+", default=["dense", "loose"])
    ap.add_argument("--media", nargs="+", default=["dry", "immersed"])
    ap.add_argument("--cores", type=float, nargs="+", default=[0.7, 0.8, 0.9, 0.95])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--tau", type=float, default=8.0, help="run length in tau_c")
    ap.add_argument("--checkpoint-every", type=int, default=200)
    ap.add_argument("--tag", default=None)
    ap.add_argument("--smoke", action="store_true", help="30 grains, 0.1 tau_c, seed 0")
    ap.add_argument("--to-rest", action="store_true",
                    help="end a run when its kinetic energy is below --stop-ratio of its peak")
    ap.add_argument("--stop-ratio", type=float, default=1e-3)
    ap.add_argument("--t-min", type=float, default=3.0, help="earliest rest, in tau_c")
    ap.add_argument("--t-max", type=float, default=20.0, help="latest end with --to-rest")
    ap.add_argument("--packing-t-max", type=float, default=3.0,
                    help="deposition time limit (s) of a packing prepared here")
    a = ap.parse_args(argv)
    if a.smoke:
        a.n, a.seeds, a.tau, a.cores, a.checkpoint_every = 30, [0], 0.1, [0.8], 10
    rest = {"stop_ratio": a.stop_ratio, "t_min": a.t_min} if a.to_rest else None
    if rest:
        a.tau = a.t_max
    tag = a.tag or ("smoke" if a.smoke else f"n{a.n}")
    root = ROOT / "out" / f"collapse_matrix_{tag}"
    out = RESULTS / f"collapse_matrix_{tag}.json"
    for seed in a.seeds:
        for state in a.states:
            for medium in a.media:
                for core in (a.cores if medium == "immersed" else [1.0]):
                    rec = one(a.n, state, medium, core, seed, a.tau, root,
                              a.checkpoint_every, rest, a.packing_t_max)
                    if rec is None:  # asked to stop: the remaining runs wait for a restart
                        return
                    print(json.dumps({k: v for k, v in rec.items() if k != "series"}),
                          flush=True)
                    record(out, rec)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
