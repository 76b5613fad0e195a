"""Force consistency: a free run's trajectory imposed again gives the same forces.

The paper's particle (bundled scene ``single_particle``: 24-gon of diameter 1 mm,
rho_p = 2650 kg/m^3 in water, Navier-Stokes, monolithic coupling, moving mesh,
dt = 1e-5 s) run for ``--t-end`` (default 40 ms) in a box tall enough that it does not
approach the floor (3 mm x 20 mm, released at y = 15 mm; it sinks about 2.2 mm), once
free, then again with the free run's trajectory (the history's ``t, x, y, angle``
columns, the start prepended) imposed as a prescribed motion
(``PrescribedMotion(trajectory=...)``), with the same steps. The free run's fluid force
is the one its rigid-body equation balances (``m a - F_ext``); the imposed run's is the
consistent reaction ``-P^T R_f`` on the same trajectory. Measured:

- the largest difference of the two force histories over the whole run, relative to
  the force then (acceptance: 0.5 %) and to the particle's immersed weight;
- the spikes on the steps after each remesh, in both runs: the largest deviation of the
  force on the first three steps on a new mesh from a quadratic fitted to the 8 steps
  before and the 8 steps from the fourth step after (acceptance: 5 % of the immersed
  weight); the same measure on steps away from remeshes gives its floor;
- optionally (``--half-step``) a replay of the same table at dt/2 (the cubic spline
  between the samples), compared at the common times.

Writes ``benchmarks/results/force_consistency.json`` and prints a markdown table.

Usage: ``python benchmarks/force_consistency.py [--t-end 0.04] [--half-step]``
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
import skfem_granular as sg
from skfem_granular.dem import PrescribedMotion
from skfem_granular.scene import Scene, TimeSpec

ROOT = Path(__file__).resolve().parents[1]
BOX = (0.0, 0.0, 3e-3, 20e-3)
START = (1.5e-3, 15e-3)


def free_scene(t_end: float, dt: float = 1e-5) -> Scene:
    """The paper's particle in the tall box (module notes); contacts off (far from walls)."""
    base = Scene.bundled("single_particle")
    p = replace(base.particles[0], polygon=sg.Polygon.regular(24, 0.5e-3, center=START))
    return replace(base, domain=BOX, particles=[p], time=TimeSpec(t_end=t_end, dt=dt),
                   output_dir=None, effects=replace(base.effects, contacts=False),
                   name="force_consistency_free")


def trajectory(scene: Scene, h) -> np.ndarray:
    """``(4, n)`` table ``t, x, y, angle`` of a run's history with the start prepended."""
    c = scene.particles[0].polygon.centroid
    return np.vstack([np.r_[0.0, h.t], np.r_[c[0], h.x[:, 0]], np.r_[c[1], h.y[:, 0]],
                      np.r_[0.0, h.angle[:, 0]]])


def imposed_scene(scene: Scene, table: np.ndarray, dt: float | None = None) -> Scene:
    p = replace(scene.particles[0], motion=PrescribedMotion(trajectory=table))
    time_spec = scene.time if dt is None else TimeSpec(t_end=scene.time.t_end, dt=dt)
    return replace(scene, particles=[p], time=time_spec, name="force_consistency_imposed")


def run(sc: Scene) -> dict:
    t0 = time.perf_counter()
    sim = sg.Simulation(sc)
    st = meshing.mesh_stats(sim.mesh)
    remesh_steps, seen = [], sim.remeshes
    for i, _ in enumerate(sim.evolve()):
        if sim.remeshes != seen:
            seen = sim.remeshes
            remesh_steps.append(i)
    h = sim.result.history
    return {"history": h, "remesh_steps": remesh_steps, "wall": time.perf_counter() - t0,
            "vertices": st.n_vertices, "dofs": int(sim.space.N), "summary": sim.result.summary}


def spikes(t, F, steps, window=8, affected=3):
    """Largest deviation of ``F`` on ``affected`` steps from each step in ``steps`` on, from
    a quadratic fitted to ``window`` steps before and ``window`` steps after them."""
    out = []
    for k in steps:
        before = np.arange(k - window, k)
        after = np.arange(k + affected, k + affected + window)
        if before[0] < 0 or after[-1] >= len(t):
            continue
        fit = np.r_[before, after]
        tau = t - t[k]
        c = np.polyfit(tau[fit], F[fit], 2)
        hit = np.arange(k, k + affected)
        out.append(float(np.abs(F[hit] - np.polyval(c, tau[hit])).max()))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--t-end", type=float, default=0.04)
    ap.add_argument("--half-step", action="store_true", help="also replay at dt/2")
    args = ap.parse_args()
    free = free_scene(args.t_end)
    out = {"benchmark": "force_consistency", "machine": platform.platform(),
           "load_avg_start": os.getloadavg(),
           "commit": subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                                    capture_output=True, text=True).stdout.strip(),
           "setup": {"box": BOX, "start": START, "t_end": args.t_end, "dt": free.time.dt,
                     "scene": "single_particle (24-gon, Navier-Stokes, monolithic, ALE)"}}
    poly = free.particles[0].polygon
    weight = (poly.area * (free.particles[0].density - free.fluid.density)
              * abs(free.gravity[1]))
    out["immersed_weight_N_per_m"] = weight
    r_free = run(free)
    h = r_free["history"]
    print(f"free: {len(h)} steps, {r_free['summary']['remeshes']} remeshes, "
          f"{r_free['wall']:.1f} s, travel {START[1] - h.y[-1, 0]:.3e} m, "
          f"v_y {h.vy[-1, 0]:.4f} m/s", flush=True)
    table = trajectory(free, h)
    r_imp = run(imposed_scene(free, table))
    g = r_imp["history"]
    print(f"imposed: {len(g)} steps, {r_imp['summary']['remeshes']} remeshes, "
          f"{r_imp['wall']:.1f} s", flush=True)
    F1 = np.stack([h.Fx[:, 0], h.Fy[:, 0]])
    F2 = np.stack([g.Fx[:, 0], g.Fy[:, 0]])
    dF = np.linalg.norm(F2 - F1, axis=0)
    mag = np.linalg.norm(F1, axis=0)
    rel = dF / np.maximum(mag, 1e-3 * weight)
    res = {"steps": len(h), "dt": free.time.dt, "vertices": r_free["vertices"],
           "dofs": r_free["dofs"], "travel_m": float(START[1] - h.y[-1, 0]),
           "final_vy": float(h.vy[-1, 0]), "final_Fy": float(h.Fy[-1, 0]),
           "remeshes_free": r_free["summary"]["remeshes"],
           "remeshes_imposed": r_imp["summary"]["remeshes"],
           "remesh_steps_free": r_free["remesh_steps"],
           "remesh_steps_imposed": r_imp["remesh_steps"],
           "max_rel_force_difference": float(rel.max()),
           "max_force_difference_over_weight": float(dF.max() / weight),
           "max_rel_force_difference_after_1ms": float(rel[h.t > 1e-3].max()),
           "max_position_difference_m": float(np.abs(g.y[:, 0] - h.y[:, 0]).max()),
           "max_velocity_difference_m_s": float(np.abs(g.vy[:, 0] - h.vy[:, 0]).max()),
           "wall_free_s": r_free["wall"], "wall_imposed_s": r_imp["wall"]}
    # remesh spikes of the vertical force (the drag), both runs, and the measure's floor
    quiet = [k for k in range(200, len(h) - 20, 97)
             if all(abs(k - r) > 20 for r in r_free["remesh_steps"])]
    for name, hist, steps in (("free", h, r_free["remesh_steps"]),
                              ("imposed", g, r_imp["remesh_steps"])):
        sp = spikes(hist.t, hist.Fy[:, 0], steps)
        res[f"remesh_spikes_{name}_over_weight"] = [v / weight for v in sp]
        res[f"remesh_spike_{name}_max_over_weight"] = max(sp, default=0.0) / weight
        res[f"floor_{name}_over_weight"] = (max(spikes(hist.t, hist.Fy[:, 0], quiet))
                                            / weight)
        res[f"force_steps_at_first_remesh_{name}"] = (
            hist.Fy[steps[0] - 2: steps[0] + 4, 0].tolist() if steps else [])
    res["consistency_ok"] = bool(rel.max() <= 5e-3)
    res["spikes_ok"] = bool(max(res["remesh_spike_free_max_over_weight"],
                                res["remesh_spike_imposed_max_over_weight"]) <= 0.05)
    out["result"] = res
    if args.half_step:
        r_half = run(imposed_scene(free, table, dt=free.time.dt / 2))
        q = r_half["history"]
        idx = np.clip(np.searchsorted(q.t, h.t), 1, len(q.t) - 1)
        idx = np.where(np.abs(q.t[idx - 1] - h.t) < np.abs(q.t[idx] - h.t), idx - 1, idx)
        ok = np.abs(q.t[idx] - h.t) < 1e-6 * free.time.dt  # the common times
        common = idx
        Fh = np.stack([q.Fx[common[ok], 0], q.Fy[common[ok], 0]])
        dh = np.linalg.norm(Fh - F1[:, ok], axis=0)
        rel_h = dh / np.maximum(mag[ok], 1e-3 * weight)
        far = np.ones(ok.sum(), dtype=bool)
        tk = h.t[ok]
        for r in r_free["remesh_steps"] + [int(np.searchsorted(h.t, q.t[k]))
                                            for k in r_half["remesh_steps"]]:
            far &= np.abs(tk - h.t[min(r, len(h.t) - 1)]) > 10 * free.time.dt
        out["half_step_replay"] = {
            "steps": len(q), "remeshes": r_half["summary"]["remeshes"],
            "remesh_steps": r_half["remesh_steps"], "wall_s": r_half["wall"],
            "max_rel_force_difference": float(rel_h.max()),
            "max_rel_force_difference_after_1ms_away_from_remeshes": float(
                rel_h[far & (tk > 1e-3)].max()),
            "max_force_difference_over_weight": float(dh.max() / weight),
            "remesh_spike_max_over_weight": max(spikes(q.t, q.Fy[:, 0], r_half["remesh_steps"],
                                                       window=16, affected=6),
                                                default=0.0) / weight}
        print("half step:", out["half_step_replay"], flush=True)
    out["load_avg_end"] = os.getloadavg()
    print()
    print("| quantity | measured | acceptance |")
    print("|---|---|---|")
    print(f"| max |F_imposed - F_free| / |F_free| (whole run) | "
          f"{res['max_rel_force_difference']:.2e} | <= 0.5 % |")
    print(f"| max |F_imposed - F_free| / weight | "
          f"{res['max_force_difference_over_weight']:.2e} | |")
    for name in ("free", "imposed"):
        print(f"| remesh spike ({name}) / weight | "
              f"{res[f'remesh_spike_{name}_max_over_weight']:.3f} (floor "
              f"{res[f'floor_{name}_over_weight']:.1e}) | <= 0.05 |")
    print(f"| remeshes | {res['remeshes_free']} / {res['remeshes_imposed']} | |")
    print(f"| wall | {res['wall_free_s']:.1f} s / {res['wall_imposed_s']:.1f} s | |")
    path = ROOT / "benchmarks/results/force_consistency.json"
    path.write_text(json.dumps(out, indent=1))
    print(f"\nwrote {path}")


if __name__ == "__main__":
    main()
