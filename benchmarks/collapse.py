"""The paper's Section 7: an n x n block of grains sedimenting in a wide box.

Runs a bundled collapse scene (5 x 5 hexagons, contacts, remeshing) to
``--t-end`` (default the scene's 0.16 s), writes VTU/PVD output to
``out/<scene>``, pictures of the initial and final states to
``docs/figures/<scene>_{initial,final}.png`` and the figures, with the mesh
size (vertices, DOFs) after every remesh, to
``benchmarks/results/<tag>.json``.

Usage::

    python benchmarks/collapse.py                       # default mesh -> collapse.json
    python benchmarks/collapse.py --scene collapse_group --tag collapse_group
    python benchmarks/collapse.py --mesh uniform --t-end 0.05 --tag collapse_uniform
    python benchmarks/collapse.py --compare             # table + DOF figure of the three

``--compare`` reads ``collapse.json``, ``collapse_group.json`` and
``collapse_uniform.json`` and writes ``collapse_compare.json`` and
``docs/figures/collapse_dofs.png``.
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

from skfem_granular.scene import Scene, bundled, grid_particles
from skfem_granular.simulation import Simulation

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks/results"
FIGS = ROOT / "docs/figures"
#: times at which the grains' mean height and spread are compared (s)
MARKS = (0.05, 0.1, 0.16)


def picture(sim, path, title):
    """Mesh, particle shadows and cores, walls."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import meshing

    fig, ax = plt.subplots(figsize=(10, 5.4))
    meshing.plot_mesh(sim.mesh, ax=ax, lw=0.2, legend=False)
    for s in sim.dem.shadow_outlines():
        ax.fill(*s, facecolor="#c8a165", edgecolor="#6b4f2a", lw=0.6, alpha=0.8)
    for c in sim.dem.core_outlines():
        ax.plot(*np.hstack([c, c[:, :1]]), color="#3b2a14", lw=0.6)
    x0, y0, x1, y1 = sim.scene.domain
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def slope_deg(sim):
    """Angle of a straight line through the top grain of each occupied column bin."""
    pos = sim.dem.positions
    r = float(np.mean([np.ptp(s[0]) / 2 for s in sim.dem.shadow_outlines()]))
    bins = np.floor(pos[0] / (2 * r)).astype(int)
    xs, ys = [], []
    for b in np.unique(bins):
        sel = bins == b
        xs.append(pos[0, sel].mean())
        ys.append(pos[1, sel].max())
    if len(xs) < 2:
        return float("nan")
    k = np.polyfit(xs, ys, 1)[0]
    return float(np.degrees(np.arctan(abs(k))))


def grains_at(h, t):
    """Mean height, horizontal spread (std of x) and width (max - min x) of the
    grains at the last recorded step <= t (m)."""
    if not len(h) or h.t[0] > t + 1e-12 or t > h.t[-1] + 1e-9:
        return None
    i = int(np.searchsorted(h.t, t + 1e-9) - 1)
    x, y = np.asarray(h.x[i]), np.asarray(h.y[i])
    return {"t": float(h.t[i]), "mean_y": float(y.mean()), "spread_x": float(x.std()),
            "width_x": float(np.ptp(x)), "mean_x": float(x.mean())}


def run(args):
    sc = Scene.bundled(args.scene)
    if args.t_end is not None:
        sc = replace(sc, time=replace(sc.time, t_end=args.t_end))
    if args.mesh is not None:
        sc = replace(sc, mesh=replace(sc.mesh, kind=args.mesh))
    if args.n != 5:
        import tomllib

        grid = tomllib.loads(bundled(args.scene).read_text())["grid"]
        sc = replace(sc, particles=tuple(grid_particles({**grid, "nx": args.n, "ny": args.n})))
    tag = args.tag or args.scene
    FIGS.mkdir(parents=True, exist_ok=True)
    load0 = list(os.getloadavg())
    t0 = time.perf_counter()
    sim = Simulation(sc, output_dir=ROOT / "out" / tag)
    picture(sim, FIGS / f"{tag}_initial.png", f"{tag}: t = 0")
    mesh_history = []

    def note(t):
        m = sim.stepper.meshed
        kind = getattr(getattr(m, "recipe", None), "kind", sc.mesh.kind)
        n_v = int(sim.mesh.p.shape[1])
        if not mesh_history or mesh_history[-1]["vertices"] != n_v or (
                mesh_history[-1]["dofs"] != int(sim.stepper.space.N)):
            mesh_history.append({"t": float(t), "vertices": n_v,
                                 "dofs": int(sim.stepper.space.N), "kind": kind})

    note(0.0)
    for t, _ in sim.evolve(progress=not args.quiet):
        note(t)
    res = sim.result
    wall = time.perf_counter() - t0
    h, s = res.history, res.summary
    picture(sim, FIGS / f"{tag}_final.png", f"{tag}: t = {h.t[-1]:.3f} s")
    try:
        commit = subprocess.run(["git", "-C", str(ROOT), "log", "-1", "--format=%h"],
                                capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = None
    dofs = [m["dofs"] for m in mesh_history]
    out = {"benchmark": "collapse", "scene": args.scene, "tag": tag, "commit": commit,
           "mesh_kind": mesh_history[-1]["kind"], "particles": sim.dem.n,
           "t_end": float(h.t[-1]), "steps": len(h), "wall_time_s": wall,
           "phases_s": s["wall_time"], "remeshes": s["remeshes"], "retries": s["retries"],
           "mesh_motion": s.get("mesh_motion"), "remesh_reasons": s.get("remesh_reasons"),
           "factorizations": s.get("factorizations"),
           "jacobian_refreshes": s.get("jacobian_refreshes"),
           "mesh_final": s["mesh"], "dofs_initial": dofs[0], "dofs_final": dofs[-1],
           "dofs_max": max(dofs), "dofs_final_over_initial": dofs[-1] / dofs[0],
           "grains": {f"{m:g}": grains_at(h, m) for m in MARKS},
           "mean_vy_final": float(h.vy[-1].mean()), "lowest_y_final": float(h.y[-1].min()),
           "contacts_final": int(h.contacts[-1].sum()), "slope_deg": slope_deg(sim),
           "max_speed": float(np.hypot(h.vx, h.vy).max()),
           "euler_steps_at_contacts": s["euler_steps_at_contacts"],
           "warnings": s["warnings"], "loadavg_start": load0,
           "loadavg_end": list(os.getloadavg()), "mesh_history": mesh_history}
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"{tag}.json").write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps({k: v for k, v in out.items() if k != "mesh_history"}, indent=1))


def compare():
    """One table and one figure from the default, group and uniform runs."""
    runs = {}
    for tag in ("collapse", "collapse_group", "collapse_uniform"):
        f = RESULTS / f"{tag}.json"
        if f.exists():
            runs[tag] = json.loads(f.read_text())
    table = {tag: {k: r.get(k) for k in ("mesh_kind", "commit", "t_end", "steps", "wall_time_s",
                                         "remeshes", "retries", "dofs_initial", "dofs_final",
                                         "dofs_max", "dofs_final_over_initial", "grains",
                                         "loadavg_start", "loadavg_end")}
             for tag, r in runs.items()}
    base = runs.get("collapse")
    if base:
        for tag, r in runs.items():
            if tag == "collapse":
                continue
            diffs = {}
            for m, g in r["grains"].items():
                b = base["grains"].get(m)
                if g and b:
                    diffs[m] = {"d_mean_y_m": g["mean_y"] - b["mean_y"],
                                "d_spread_x_m": g["spread_x"] - b["spread_x"]}
            table[tag]["vs_default"] = diffs
    (RESULTS / "collapse_compare.json").write_text(json.dumps(table, indent=1) + "\n")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    for tag, r in runs.items():
        mh = r["mesh_history"]
        t = [m["t"] for m in mh] + [r["t_end"]]
        d = [m["dofs"] for m in mh] + [mh[-1]["dofs"]]
        ax.step(t, d, where="post", label=f"{tag} ({r['mesh_kind']})")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("DOFs (P2/P1)")
    ax.set_yscale("log")
    ax.legend()
    ax.set_title("collapse: mesh size over time")
    fig.tight_layout()
    fig.savefig(FIGS / "collapse_dofs.png", dpi=130)
    plt.close(fig)
    print(json.dumps(table, indent=1))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="collapse")
    ap.add_argument("--mesh", default=None, help="override mesh.kind (e.g. uniform)")
    ap.add_argument("--t-end", type=float, default=None)
    ap.add_argument("--n", type=int, default=5)
    ap.add_argument("--tag", default=None, help="results/<tag>.json (default: the scene)")
    ap.add_argument("--quiet", action="store_true")
    ap.add_argument("--compare", action="store_true")
    args = ap.parse_args()
    if args.compare:
        compare()
    else:
        run(args)


if __name__ == "__main__":
    main()
