"""Grain size in water: the same immersed collapse with larger grains.

Usage::

    python benchmarks/collapse_grain_size.py --seed 0                  # 200 grains, 1.7 mm
    python benchmarks/collapse_grain_size.py --seed 1 --d-mean 1.7e-3 --tau 5
    python benchmarks/collapse_grain_size.py --report --figure docs/figures/collapse_grain_size.png

Dry, a column of ``n`` grains collapses the same way whatever their size once time is
measured in ``tau_c = sqrt(H0 / g)``. In water it does not: the pore fluid drains
through the column at a Darcy speed ``K (rho_p - rho_f) g / mu`` with a permeability
``K`` proportional to ``d^2``, against the column's speed scale ``sqrt(g H0)``
proportional to ``sqrt(d)`` at a fixed number of grains, so larger grains drain faster
relative to ``tau_c`` (by ``d^(3/2)``). This script prepares the column of
:func:`skfem_granular.packing.prepare_column` with a mean diameter ``--d-mean`` (same
protocol, seed and size ratio; the contact stiffness scaled with the diameter,
``E = 1e6 N/m x d_mean / 1 mm``, so that the resting overlaps are the same fraction of a
grain) and runs it in water (:func:`skfem_granular.collapse.column_scene`, core ratio
``--core``, 0.2 ms steps, ``--tau`` ``tau_c``), checkpointing every 100 steps (run it
again to continue). ``--report`` writes, for these runs and for the 1 mm runs of the
200-grain matrix (``results/collapse_matrix_n200.json``, same state and core ratio),
when the grains' kinetic energy ``E_x + E_y`` peaks and how much of it is left at 4, 5
and 6 ``tau_c``, to ``benchmarks/results/collapse_grain_size.json``, with the series;
``--figure`` draws the kinetic energy over its peak and the run-out of both against
``t / tau_c``.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks/results"
PACKINGS = RESULTS / "packings"
OUT = ROOT / "out/collapse_grain_size"
ASPECT = 0.8


def column(n: int, state: str, seed: int, d_mean: float):
    """The column of ``d_mean`` grains (stiffness scaled with the diameter), prepared once
    and kept in ``results/packings`` (:func:`skfem_granular.studies.cached_packing`)."""
    from skfem_granular.studies import cached_packing

    return cached_packing(n, state, seed, PACKINGS, aspect=ASPECT, d_mean=d_mean,
                          E=1e6 * d_mean / 1e-3)


def run_name(n, state, core, seed, d_mean) -> str:
    return f"{state}_immersed_core{core:g}_s{seed}_n{n}_d{d_mean * 1e3:g}mm"


def run(n: int, state: str, core: float, seed: int, d_mean: float, tau: float) -> None:
    """Run (or continue) one collapse; its cost goes to ``cost.json`` in its folder."""
    from skfem_granular.collapse import column_scene, time_scale
    from skfem_granular.simulation import Simulation

    pk = column(n, state, seed, d_mean)
    folder = OUT / run_name(n, state, core, seed, d_mean)
    c0, w0 = time.process_time(), time.perf_counter()
    if (folder / "checkpoint.npz").exists():
        sim = Simulation.resume(folder)
    else:
        scene = column_scene(pk, fluid=True, core_ratio=core, t_end=tau * time_scale(pk),
                             name=folder.name, output_dir=str(folder), vtu_every=250)
        sim = Simulation(replace(scene, checkpoint_every=100), overwrite=True)
    dofs = [int(sim.space.N) for _ in sim.evolve(progress=False)]
    cost_path = folder / "cost.json"
    cost = json.loads(cost_path.read_text()) if cost_path.exists() else {
        "cpu_s": 0.0, "wall_s": 0.0, "processes": 0, "dofs": []}
    cost["cpu_s"] += time.process_time() - c0
    cost["wall_s"] += time.perf_counter() - w0
    cost["processes"] += 1
    cost["dofs"] += dofs[:: max(len(dofs) // 50, 1)]
    cost_path.write_text(json.dumps(cost) + "\n")


def energy_record(t_over_tau, E) -> dict:
    """When the kinetic energy peaks, and the fraction of the peak left at 4, 5 and 6 tau_c
    (None past the run's end)."""
    t, E = np.asarray(t_over_tau), np.asarray(E)
    i = int(np.argmax(E))

    def left(x):
        return float(np.interp(x, t, E) / E[i]) if t[-1] >= x else None

    return {"t_peak_over_tau": float(t[i]), "E_over_peak_at_4": left(4.0),
            "E_over_peak_at_5": left(5.0), "E_over_peak_at_6": left(6.0),
            "t_end_over_tau": float(t[-1])}


def report(n: int, state: str, core: float, d_mean: float) -> dict:
    """The record of the runs of ``d_mean`` grains beside the 1 mm runs of the matrix."""
    from skfem_granular.collapse import (
        collapse_series,
        column_scene,
        history_columns,
        realisations,
        time_scale,
    )

    runs = []
    for folder in sorted(OUT.glob(run_name(n, state, core, "*", d_mean))):
        summary = json.loads((folder / "summary.json").read_text())
        seed = int(folder.name.split("_s")[1].split("_")[0])
        pk = column(n, state, seed, d_mean)
        cols = history_columns(folder / "history.csv")
        s = collapse_series(cols, pk, column_scene(pk, fluid=False).domain)
        cost = json.loads((folder / "cost.json").read_text())
        every_fifth = np.unique(np.r_[np.arange(0, s["t"].size, 5), s["t"].size - 1])
        runs.append({"run": folder.name, "seed": seed, "d_mean": pk.d_mean,
                     "d_max": pk.d_max, "E": pk.E, "solid_fraction": pk.solid_fraction,
                     "aspect": pk.aspect, "H0": pk.height, "tau_c": time_scale(pk),
                     "status": summary.get("status"), "steps": summary.get("steps"),
                     "retries": summary.get("retries"), "remeshes": summary.get("remeshes"),
                     "cpu_s": cost["cpu_s"], "dofs_mean": float(np.mean(cost["dofs"])),
                     **energy_record(s["t_over_tau"], np.add(s["E_x"], s["E_y"])),
                     "runout_at_end": float(s["runout"][-1]),
                     "series": {k: np.asarray(s[k])[every_fifth].tolist()
                                for k in ("t_over_tau", "runout", "E_x", "E_y")}})
    matrix = json.loads((RESULTS / "collapse_matrix_n200.json").read_text())["runs"]
    ref = [{"run": r["run"], "seed": r["seed"], "d_mean": 1e-3,
            "solid_fraction": r["solid_fraction"], "tau_c": r["tau_c"],
            "series": {k: r["series"][k] for k in ("t_over_tau", "runout", "E_x", "E_y")},
            **energy_record(r["series"]["t_over_tau"],
                            np.add(r["series"]["E_x"], r["series"]["E_y"]))}
           for r in matrix if r["state"] == state and r["medium"] == "immersed"
           and r["core_ratio"] == core] if n == 200 else []

    def stats(rs, key):  # over the seeds that reached the time asked for
        v = [r[key] for r in rs if r.get(key) is not None]
        return realisations(v) if v else None

    return {"benchmark": "collapse_grain_size", "grains": n, "state": state,
            "core_ratio": core, "aspect": ASPECT, "runs": runs, "reference_1mm": ref,
            "summary": {f"d{d * 1e3:g}mm": {k: stats(rs, k) for k in (
                "t_peak_over_tau", "E_over_peak_at_4", "E_over_peak_at_5",
                "E_over_peak_at_6")}
                for d, rs in ((d_mean, runs), (1e-3, ref)) if rs}}


def figure(rec: dict, path: Path) -> None:
    """Kinetic energy over its peak, and run-out, against ``t / tau_c``: both grain sizes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_e, ax_r) = plt.subplots(1, 2, figsize=(10, 3.8))
    for runs, colour, label in ((rec["reference_1mm"], "C0", "1 mm"),
                                (rec["runs"], "C3", f"{rec['runs'][0]['d_mean'] * 1e3:g} mm")):
        for k, r in enumerate(runs):
            s = r["series"]
            E = np.add(s["E_x"], s["E_y"])
            kw = {"color": colour, "lw": 1.2, "label": label if k == 0 else None}
            ax_e.plot(s["t_over_tau"], E / E.max(), **kw)
            ax_r.plot(s["t_over_tau"], s["runout"], **kw)
    ax_e.set_ylabel(r"$(E_x + E_y) / \max$")
    ax_r.set_ylabel(r"run-out $(L - L_0) / L_0$ (gap front)")
    for ax in (ax_e, ax_r):
        ax.set_xlabel(r"$t / \tau_c$")
        ax.set_xlim(0.0, max(r["series"]["t_over_tau"][-1] for r in rec["runs"]))
        ax.legend(title=f"{rec['state']}, core {rec['core_ratio']:g}, {rec['grains']} grains")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--state", default="dense", choices=["dense", "loose"])
    ap.add_argument("--core", type=float, default=0.9)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--d-mean", type=float, default=1.7e-3, help="mean diameter (m)")
    ap.add_argument("--tau", type=float, default=5.0, help="run length in tau_c")
    ap.add_argument("--report", action="store_true")
    ap.add_argument("--figure", type=Path, default=None, help="with --report: a PNG")
    a = ap.parse_args(argv)
    if not 0.0 < a.d_mean < 0.1:
        raise SystemExit(f"--d-mean {a.d_mean!r}: must be in (0, 0.1) m")
    if a.report:
        rec = report(a.n, a.state, a.core, a.d_mean)
        out = RESULTS / "collapse_grain_size.json"
        out.write_text(json.dumps(rec, indent=1) + "\n")
        if a.figure is not None:
            figure(rec, a.figure)
        print(json.dumps(rec["summary"], indent=1))
        return
    run(a.n, a.state, a.core, a.seed, a.d_mean, a.tau)


if __name__ == "__main__":
    main()
