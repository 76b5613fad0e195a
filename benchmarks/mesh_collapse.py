"""Benchmark: the default (field) mesh along the bundled collapse.

Usage: ``python benchmarks/mesh_collapse.py [--t-end T]``. Runs the bundled
``collapse`` scene (its default mesh, moving mesh, remeshing) to ``--t-end``
(default the scene's 0.16 s) without writing any output but
``benchmarks/results/mesh_collapse.json``: DOFs and vertices after every
remesh, the smallest angle of every new mesh, wall time, remeshes, and the
grains' mean height and spread at 0.05 / 0.1 / 0.16 s (the figures of
``benchmarks/collapse.py``, whose pictures and VTU output this run leaves alone).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

import meshing
from skfem_granular.scene import Scene
from skfem_granular.simulation import Simulation

ROOT = Path(__file__).resolve().parents[1]
MARKS = (0.05, 0.1, 0.16)


def grains_at(h, t):
    """Mean height and horizontal spread (std of x) at the last step <= t (m)."""
    if not len(h) or t > h.t[-1] + 1e-9:
        return None
    i = int(np.searchsorted(h.t, t + 1e-9) - 1)
    x, y = np.asarray(h.x[i]), np.asarray(h.y[i])
    return {"t": float(h.t[i]), "mean_y": float(y.mean()), "spread_x": float(x.std())}


def run(t_end, output):
    sc = Scene.bundled("collapse")
    if t_end is not None:
        sc = replace(sc, time=replace(sc.time, t_end=t_end))
    sc = replace(sc, output_dir=None)
    load0 = list(os.getloadavg())
    t0 = time.perf_counter()
    sim = Simulation(sc)
    history = []

    def note(t):
        m = sim.stepper.meshed
        mesh = getattr(m, "mesh", m)
        if not history or history[-1]["mesh_id"] != id(mesh):
            s = meshing.mesh_stats(mesh)
            history.append({"t": float(t), "mesh_id": id(mesh), "vertices": s.n_vertices,
                            "dofs": int(sim.stepper.space.N), "min_angle_deg": s.min_angle,
                            "max_aspect": s.max_aspect})

    note(0.0)
    for t, _ in sim.evolve(progress=False):
        note(t)
    wall = time.perf_counter() - t0
    res = sim.result
    h, s = res.history, res.summary
    for m in history:
        del m["mesh_id"]
    dofs = [m["dofs"] for m in history]
    commit = subprocess.run(["git", "-C", str(ROOT), "log", "-1", "--format=%h"],
                            capture_output=True, text=True).stdout.strip() or None
    out = {"benchmark": "mesh_collapse", "commit": commit, "machine": platform.platform(),
           "t_end": float(h.t[-1]), "steps": len(h), "wall_time_s": wall,
           "phases_s": s["wall_time"], "remeshes": s["remeshes"],
           "dofs_initial": dofs[0], "dofs_final": dofs[-1], "dofs_max": max(dofs),
           "dofs_final_over_initial": dofs[-1] / dofs[0],
           "min_angle_deg": min(m["min_angle_deg"] for m in history),
           "grains": {f"{m:g}": grains_at(h, m) for m in MARKS},
           "loadavg_start": load0, "loadavg_end": list(os.getloadavg()),
           "meshes": history}
    Path(output).parent.mkdir(parents=True, exist_ok=True)
    Path(output).write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps({k: v for k, v in out.items() if k != "meshes"}, indent=1))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--t-end", type=float, default=None)
    ap.add_argument("--output",
                    default=str(ROOT / "benchmarks" / "results" / "mesh_collapse.json"))
    args = ap.parse_args(argv)
    run(args.t_end, args.output)


if __name__ == "__main__":
    main()
