"""Benchmark: the budget's memory estimate against the measured peak of real runs.

Usage::

    python benchmarks/memory_estimate.py [--cases n25,n100,n400,n1000,sp1e-5]
        [--schemes monolithic,split] [--steps 10] [--tag NAME]

Each case runs ``--steps`` steps in a fresh interpreter (one thread): ``n<N>`` the dense
collapse column of ``N`` grains at core ratio 0.9 (dt 2e-4 s), ``sp<delta_l>`` the
paper's single particle on a graded mesh of that outline edge. Records the estimate made
before meshing (:meth:`skfem_granular.simulation.Budget.check_mesh`: the triangle
model), the estimate from the built mesh's unknowns
(:func:`skfem_granular.simulation.budget.peak_memory`), the peak resident memory of the
process (``ru_maxrss``) and their ratios. Writes
``benchmarks/results/memory_estimate_<tag>.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from child_process import run_child  # noqa: E402
from record import commit, machine  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PACKINGS = ROOT / "benchmarks" / "results" / "packings"


def _scene(case: str, scheme: str, steps: int):
    from dataclasses import replace

    from skfem_granular.scene import Scene

    if case.startswith("sp"):
        sc = replace(Scene.bundled("single_particle"), output_dir=None)
        sc = replace(sc, mesh=replace(sc.mesh, delta_l=float(case[2:])))
    else:
        from skfem_granular.collapse import column_scene
        from skfem_granular.packing import load_packing

        pk = load_packing(PACKINGS / f"dense_a0.8_n{int(case[1:])}_seed0.npz")
        sc = column_scene(pk, fluid=True, core_ratio=0.9, t_end=2e-4, dt=2e-4)
    return replace(sc, coupling=scheme, time=replace(sc.time, t_end=steps * sc.time.dt))


def child(case: str, scheme: str, steps: int) -> dict:
    import resource
    import time

    from skfem_granular.simulation import Budget, Simulation
    from skfem_granular.simulation.budget import peak_memory, taylor_hood_unknowns

    scene = _scene(case, scheme, steps)
    estimates = {}

    class Recording(Budget):
        def check_mesh(self, scene, cores):
            est = super().check_mesh(scene, cores)
            estimates["before_meshing"] = {"unknowns": est.unknowns, "bytes": est.memory}
            return est

    t0 = time.process_time()
    sim = Simulation(scene, budget=Recording(max_memory=1e12))
    unknowns = taylor_hood_unknowns(sim.mesh)
    estimates["built_mesh"] = {"unknowns": unknowns, "bytes": peak_memory(unknowns, scheme)}
    result = sim.run(progress=False)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024.0
    return {"case": case, "scheme": scheme, "steps": len(result.history.t) - 1,
            "status": sim.status, "remeshes": result.summary.get("remeshes"),
            "cpu_s": time.process_time() - t0, "peak_bytes": peak, "estimates": estimates,
            "ratio_before_meshing": estimates["before_meshing"]["bytes"] / peak,
            "ratio_built_mesh": estimates["built_mesh"]["bytes"] / peak}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", default="n25,n100,n400,n1000,sp1e-5")
    ap.add_argument("--schemes", default="monolithic,split")
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--tag", default="default")
    ap.add_argument("--child", nargs=3, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        case, scheme, steps = args.child
        print(json.dumps(child(case, scheme, int(steps))))
        return 0
    out = {"benchmark": "memory_estimate", "commit": commit(), "machine": machine(),
           "loadavg_start": os.getloadavg(), "steps": args.steps, "runs": []}
    path = ROOT / "benchmarks" / "results" / f"memory_estimate_{args.tag}.json"
    for case in args.cases.split(","):
        for scheme in args.schemes.split(","):
            rec = run_child(__file__, case, scheme, args.steps)
            out["runs"].append(rec)
            print(f"{case} {scheme}: peak {rec['peak_bytes'] / 1e9:.3f} GB, estimate before "
                  f"meshing x{rec['ratio_before_meshing']:.2f}, from the mesh "
                  f"x{rec['ratio_built_mesh']:.2f}", flush=True)
            path.write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
