"""The paper's Section 7: an n x n block of grains sedimenting in a wide box.

Runs the bundled ``collapse`` scene (5 x 5 hexagons, group mesh, contacts,
remeshing) to ``--t-end`` (default the scene's 0.16 s), writes VTU/PVD output
to ``out/collapse``, a picture of the initial and final states to
``docs/figures/collapse_{initial,final}.png`` and the figures to
``benchmarks/results/collapse.json``.

Usage: ``python benchmarks/collapse.py [--t-end 0.16] [--n 5]``
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from skfem_granular.scene import Scene, bundled, grid_particles
from skfem_granular.simulation import Simulation

ROOT = Path(__file__).resolve().parents[1]


def picture(sim, path, title):
    """Mesh (fine/graded), particle shadows and cores, walls."""
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


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--t-end", type=float, default=None)
    ap.add_argument("--n", type=int, default=5)
    args = ap.parse_args()
    sc = Scene.bundled("collapse")
    if args.t_end is not None:
        sc = replace(sc, time=replace(sc.time, t_end=args.t_end))
    if args.n != 5:
        import tomllib

        grid = tomllib.loads(bundled("collapse").read_text())["grid"]
        sc = replace(sc, particles=tuple(grid_particles({**grid, "nx": args.n, "ny": args.n})))
    figs = ROOT / "docs/figures"
    figs.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    sim = Simulation(sc, output_dir=ROOT / "out/collapse")
    picture(sim, figs / "collapse_initial.png", "t = 0")
    res = sim.run(progress=True)
    wall = time.perf_counter() - t0
    h, s = res.history, res.summary
    picture(sim, figs / "collapse_final.png", f"t = {h.t[-1]:.3f} s")
    out = {"benchmark": "collapse", "particles": sim.dem.n, "t_end": float(h.t[-1]),
           "steps": len(h), "wall_time_s": wall, "phases_s": s["wall_time"],
           "remeshes": s["remeshes"], "retries": s["retries"], "mesh_final": s["mesh"],
           "mean_vy_final": float(h.vy[-1].mean()), "lowest_y_final": float(h.y[-1].min()),
           "contacts_final": int(h.contacts[-1].sum()), "slope_deg": slope_deg(sim),
           "max_speed": float(np.hypot(h.vx, h.vy).max()),
           "euler_steps_at_contacts": s["euler_steps_at_contacts"],
           "warnings": s["warnings"], "loadavg_end": list(__import__("os").getloadavg())}
    (ROOT / "benchmarks/results/collapse.json").write_text(json.dumps(out, indent=1))
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
