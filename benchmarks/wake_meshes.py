"""A disk released just off the centreline at Re ~350: does the mesh let its wake shed?

The set-up of ``benchmarks/settling_re350.py`` (2.5 mm 64-gon, rho_p / rho_f = 1.5,
nu = 1e-6 m^2/s, closed 2 x 6 cm channel, steps of 0.25 ms or ``--dt``), released ``--offset``
(default 10 um) right of the centreline 2 cm below the top of a channel ``--height``
high (default 6 cm: the original's (1, 4) cm), run to ``--t-end`` (default 0.32 s) on one
mesh: ``--mesh graded`` (the default mesh, ``--sigma`` optional), ``field`` (graded
from the nearest outline) or ``flow`` (``field`` graded by the vorticity as well at
every remesh: ``CoupledStepper.flow_sizing = FlowSizing(--eps, --budget)``). The
default graded mesh refines itself above a particle Reynolds number of 40
(``[mesh] wake``, :mod:`skfem_granular.coupled.wake`); ``--no-wake`` keeps the paper's
circles throughout (the default mesh before that rule).
Records the lateral offset ``x - x0`` over time (largest, final), the largest
Reynolds number, mesh sizes and the wall time.

``--delta-l`` and ``--wake-sigma`` refine the default graded mesh (outline edges, and
the circles above Re 40). ``--analyse TAG ...`` prints the oscillation of stored runs
(:func:`skfem_granular.validation.oscillation.oscillation`: period, amplitude, mean
offset and Strouhal number from the extrema of the lateral offset in ``--window``,
default 0.65-1.04 s) instead of running.

Writes ``benchmarks/results/wake_meshes_<tag>.json``.

Usage: ``python benchmarks/wake_meshes.py --mesh flow --tag flow``;
``python benchmarks/wake_meshes.py --analyse tall_field tall_flow``
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import time
from pathlib import Path

import numpy as np

import meshing
from skfem_granular.coupled.flow_size import FlowSizing
from skfem_granular.coupled.wake import WakeGrading
from skfem_granular.scene import Scene
from skfem_granular.simulation import Simulation
from skfem_granular.validation.oscillation import oscillation

ROOT = Path(__file__).resolve().parents[1]


def scene(kind: str, offset: float, t_end: float, sigma: float | None,
          height: float = 0.06, wake: bool = True, delta_l: float | None = None,
          dt: float = 2.5e-4) -> Scene:
    mesh = {"kind": "field" if kind in ("field", "flow") else "graded", "wake": wake}
    if sigma is not None:
        mesh["sigma"] = sigma
    if delta_l is not None:
        mesh["delta_l"] = delta_l
    return Scene.from_dict({
        "domain": {"box": [0.0, 0.0, 0.02, height]},
        "fluid": {"density": 1000.0, "viscosity": 1e-3},
        "particles": [{"sides": 64, "radius": 1.25e-3, "center": [0.01 + offset, height - 0.02],
                       "density": 1500.0}],
        "mesh": mesh, "effects": {"contacts": False},
        "time": {"t_end": t_end, "dt": dt}}, name="wake_meshes")


def analyse(tags: list[str], window: tuple[float, float] = (0.65, 1.04)) -> None:
    """Print the :func:`oscillation` of stored runs ``wake_meshes_<tag>.json``, one line each."""
    for tag in tags:
        r = json.loads((ROOT / f"benchmarks/results/wake_meshes_{tag}.json").read_text())
        h = r["history"]
        o = oscillation(h["t"], h["dx"], h["vy"], 2.5e-3, window)
        dofs = r.get("dofs") or [None]
        print(f"{tag}: vertices {r['vertices'][0]} / {max(r['vertices'])}, DOFs {dofs[0]} / "
              f"{max(dofs, key=lambda n: n or 0)}, smallest angle {min(r['min_angles']):.1f}, "
              f"period {o['period']:.4f} s ({o['periods'][0]:.4f}-{o['periods'][1]:.4f}), "
              f"amplitude {o['amplitude'] * 1e6:.0f} um, mean {o['mean'] * 1e6:+.0f} um, "
              f"{o['extrema']} extrema, St {o['strouhal']:.3f} (U = {o['U'] * 100:.2f} cm/s), "
              f"CPU {r.get('cpu_s') or float('nan'):.0f} s, wall {r['wall_s']:.0f} s")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--mesh", choices=["graded", "field", "flow"], default="graded")
    ap.add_argument("--sigma", type=float, default=None)
    ap.add_argument("--offset", type=float, default=10e-6)
    ap.add_argument("--t-end", type=float, default=0.32)
    ap.add_argument("--eps", type=float, default=0.1)
    ap.add_argument("--budget", type=int, default=20_000)
    ap.add_argument("--height", type=float, default=0.06,
                    help="channel height (m); released 2 cm below the top")
    ap.add_argument("--no-wake", action="store_true",
                    help="keep the default graded mesh's circles at every Reynolds number")
    ap.add_argument("--delta-l", type=float, default=None,
                    help="outline edge length (m); default: the 64-gon's edges, 0.123 mm")
    ap.add_argument("--wake-sigma", type=float, default=None,
                    help="growth factor of the default graded mesh's circles above Re 40 "
                         "(default 1.05, WAKE_SIGMA)")
    ap.add_argument("--dt", type=float, default=2.5e-4, help="time step (s)")
    ap.add_argument("--tag", default=None)
    ap.add_argument("--analyse", nargs="+", metavar="TAG", default=None,
                    help="print the oscillation of stored runs (in --window) and stop")
    ap.add_argument("--window", type=float, nargs=2, default=(0.65, 1.04),
                    metavar=("T0", "T1"), help="time window of --analyse (s)")
    a = ap.parse_args()
    if a.analyse:
        return analyse(a.analyse, tuple(a.window))
    sim = Simulation(scene(a.mesh, a.offset, a.t_end, a.sigma, a.height, wake=not a.no_wake,
                           delta_l=a.delta_l, dt=a.dt))
    if a.wake_sigma is not None:
        sim.stepper.wake_grading = WakeGrading(sigma=a.wake_sigma)
    if a.mesh == "flow":
        sim.stepper.flow_sizing = FlowSizing(eps=a.eps, budget=a.budget)
    sizes = []
    t0, c0 = time.perf_counter(), time.process_time()
    failed = None
    try:
        for _ in sim.evolve():
            if not sizes or sizes[-1][1] != sim.mesh.p.shape[1]:
                sizes.append((float(sim.stepper.state.t), int(sim.mesh.p.shape[1]),
                              float(meshing.mesh_stats(sim.mesh).min_angle),
                              sim.stepper.meshed.recipe.options.get("sigma"),
                              int(sim.stepper.space.N),
                              getattr(sim.stepper.coupling.solver, "name", None)))
            if len(sim.history.t) % round(0.05 / a.dt) == 0:  # progress, every 50 ms
                print(f"t = {sim.stepper.state.t:.3f} s, {time.process_time() - c0:.0f} CPU s, "
                      f"{sim.mesh.p.shape[1]} vertices", flush=True)
    except Exception as exc:  # a run that stops still reports what it measured
        failed = str(exc)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    h = sim.history
    t, x, vy = np.asarray(h.t), np.asarray(h.x[:, 0]), np.asarray(h.vy[:, 0])
    dx = x - (0.01 + a.offset)
    every = max(1, round(1e-3 / a.dt))                       # the history every 1 ms
    out = {"benchmark": "wake_meshes", "mesh": a.mesh, "sigma": a.sigma, "offset": a.offset,
           "height": a.height,
           "eps": a.eps if a.mesh == "flow" else None,
           "budget": a.budget if a.mesh == "flow" else None, "t_end": float(t[-1]),
           "wake": not a.no_wake, "delta_l": a.delta_l, "wake_sigma": a.wake_sigma, "dt": a.dt,
           "failed": failed, "steps": len(t), "remeshes": sim.remeshes, "wall_s": wall,
           "cpu_s": cpu,
           "re_max": float(1000.0 * np.abs(vy).max() * 2.5e-3 / 1e-3),
           "lateral_max": float(np.abs(dx).max()), "lateral_final": float(dx[-1]),
           "t_lateral_max": float(t[int(np.argmax(np.abs(dx)))]),
           "vertices": [s[1] for s in sizes], "min_angles": [s[2] for s in sizes],
           "mesh_times": [s[0] for s in sizes], "mesh_sigmas": [s[3] for s in sizes],
           "dofs": [s[4] for s in sizes], "solvers": sorted({str(s[5]) for s in sizes}),
           "history": {k: v[::every].tolist() for k, v in (("t", t), ("dx", dx), ("vy", vy))},
           "machine": platform.platform(),
           "commit": subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                                    capture_output=True, text=True).stdout.strip()}
    tag = a.tag or a.mesh
    (ROOT / f"benchmarks/results/wake_meshes_{tag}.json").write_text(json.dumps(out, indent=1))
    print(json.dumps({k: out[k] for k in ("mesh", "t_end", "failed", "remeshes", "re_max",
                                          "lateral_max", "lateral_final", "wall_s",
                                          "cpu_s")}))
    print("vertices per mesh:", out["vertices"][:5], "...", out["vertices"][-3:])


if __name__ == "__main__":
    main()
