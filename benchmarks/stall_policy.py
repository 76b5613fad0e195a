"""Benchmark: what a stalled chord iteration costs, fluid alone and coupled.

Usage: ``python benchmarks/stall_policy.py [--cases cyl,cyl_fixed,collapse] [--tag NAME]``.

Cases (CPU time by ``time.process_time``, the whole case in one process):

- ``cyl``: a cylinder started impulsively at Re = U d / nu = 100 in a closed channel
  (the test of the adaptive steps in ``tests/test_hard_cases.py``: graded mesh, sigma
  1.15, 6k DOFs), adaptive ``fluid.evolve`` to t = 1.5;
- ``cyl_fixed``: the same at fixed dt = 0.01 to t = 1;
- ``cyl_fine``: the same at fixed steps on a finer mesh (192-gon, sigma 1.06, 52k DOFs);
- ``single_particle``: the paper's single particle (bundled scene, 1 ms);
- ``collapse``: the bundled collapse to 0.04 s.

For each: steps, corrector iterations, factorisations, Jacobian refreshes (steps where
the chord iteration stalled), the drag (fluid) or the last history row (coupled). Run it
with another checkout first on ``PYTHONPATH`` to compare two versions (the fluid
integrator switched to GMRES on the exact Jacobian before it shared the coupling's stall
policy). Writes ``benchmarks/results/stall_policy[_TAG].json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

import meshing
import skfem_granular as sg
from skfem_granular.scene import Scene
from skfem_granular.simulation import Simulation

ROOT = Path(__file__).resolve().parents[1]


def fluid_case(n: int, sigma: float, **steps) -> dict:
    """The Re-100 cylinder on a graded mesh around an ``n``-gon."""
    disk = sg.Polygon.regular(n, 0.5, center=(0.0, 0.0))
    mesh = meshing.graded_mesh((-4.0, -2.0, 12.0, 2.0), [disk.vertices], sigma=sigma)
    space = sg.TaylorHood(mesh)
    bc = {"wall": (0.0, 0.0), "particle0": (-1.0, 0.0)}
    c0 = time.process_time()
    infos, flow = [], None
    for _, flow in sg.evolve(space, sg.Fluid(1.0, 0.01), bc, **steps):
        infos.append(flow.step)
    assert flow is not None
    cpu = time.process_time() - c0
    F = flow.force("particle0")
    refreshes = sum(getattr(s, "refreshes", 0) for s in infos)
    return {"dofs": int(space.N), "cpu_s": cpu, "steps": len(infos),
            "rejected": sum(s.rejected for s in infos),
            "iterations": sum(s.iterations for s in infos),
            "stalled_steps": sum(bool(getattr(s, "refreshes", getattr(s, "gmres", 0)))
                                 for s in infos),
            "jacobian_refreshes": refreshes, "final_t": repr(flow.t),
            "factorizations": flow.report.solver["factorizations"],
            "linear_solves": flow.report.solver["solves"], "drag": float(F[0])}


def coupled_case(name: str, t_end: float | None = None, seed: int | None = None) -> dict:
    """A bundled scene, no output written (``seed``: the collapse's grid seeded so)."""
    if seed is not None and name == "collapse":
        from gap_lining import seeded_collapse

        sc = seeded_collapse(seed)
    else:
        sc = Scene.bundled(name)
    if t_end is not None:
        sc = replace(sc, time=replace(sc.time, t_end=t_end))
    c0 = time.process_time()
    sim = Simulation(replace(sc, output_dir=None))
    h = sim.run(progress=False).history
    cpu = time.process_time() - c0
    st = sim.stepper
    marks = [t for t in (0.05, 0.1, 0.16) if t <= h.t[-1] + 1e-12]
    rows = [int(np.argmin(np.abs(h.t - t))) for t in marks]
    at = list(zip(marks, rows, strict=True))
    return {"cpu_s": cpu, "steps": len(h), "iterations": int(h.iterations.sum()),
            **st.factor_counts, "remeshes": st.remeshes, "final_t": repr(float(h.t[-1])),
            "vy_end": float(h.vy[-1, 0]), "y_end": float(h.y[-1, 0]),
            "mean_height": {f"{t:g}": float(h.y[k].mean()) for t, k in at},
            "height_spread": {f"{t:g}": float(h.y[k].std()) for t, k in at}}


#: The collapse's grid seed (``--seed``; None: the bundled scene's own, 1).
SEED: list = [None]

CASES = {
    "cyl": lambda: fluid_case(48, 1.15, dt=1e-3, t_end=1.5, adaptive=True, tol=1e-3),
    "cyl_fixed": lambda: fluid_case(48, 1.15, dt=0.01, t_end=1.0),
    "cyl_fine": lambda: fluid_case(192, 1.06, dt=0.01, t_end=1.0),
    "single_particle": lambda: coupled_case("single_particle"),
    "collapse": lambda: coupled_case("collapse", 0.04),
    "collapse_full": lambda: coupled_case("collapse", seed=SEED[0]),
}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", default="cyl,cyl_fixed,single_particle,collapse")
    ap.add_argument("--tag", default="")
    ap.add_argument("--seed", type=int, default=None, help="the collapse grid's seed")
    ap.add_argument("--stall-rule", default=None,
                    help="'rate:R' or 'amortised:N' in place of the library's rule")
    args = ap.parse_args()
    from scaling_contact import set_stall_rule

    set_stall_rule(args.stall_rule)
    SEED[0] = args.seed
    out = {"package": sg.__file__, "machine": platform.machine(),
           "stall_rule": args.stall_rule or "library", "seed": args.seed,
           "load_before": os.getloadavg()[0], "cases": {}}
    for name in args.cases.split(","):
        out["cases"][name] = r = CASES[name]()
        print(name, json.dumps(r))
    out["load_after"] = os.getloadavg()[0]
    suffix = f"_{args.tag}" if args.tag else ""
    path = ROOT / "benchmarks" / "results" / f"stall_policy{suffix}.json"
    path.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
