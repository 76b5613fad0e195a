"""Benchmark: a window of a long run, continued from its checkpoint.

The 1000-grain collapses run for hours; what a change to the code does to them is
measured on a few of their steps. This script copies a run's checkpoint (and the
history.csv it follows) into a scratch folder (the run itself is not touched),
resumes it there and simulates
``--steps`` steps, timing the resume (the first mesh's set-up) and every step (wall
and CPU), with the run's phase timers, its remeshes and factorisations and the DOFs.
The same checkpoint under two versions of the code gives the same steps (the
collapse is deterministic), so their costs compare step for step; run the versions
one after the other (``PYTHONPATH`` at a checkout of each) and compare ratios.

Usage::

    python benchmarks/resume_window.py out/collapse_matrix_n1000/loose_immersed_core0.9_s0 \\
        --steps 12 --out benchmarks/results/resume_window_loose.json
    python benchmarks/resume_window.py RUN --coupling split   # the window on the split solver
    python benchmarks/resume_window.py RUN --mesh-repair none # remeshes instead of repairs
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import time
from pathlib import Path

from run_copy import check_run, run_argument, scratch_copy

ROOT = Path(__file__).resolve().parents[1]


def commit_of(path: Path) -> str:
    """The commit of the checkout that ``skfem_granular`` is imported from."""
    r = subprocess.run(["git", "-C", str(path), "rev-parse", "--short", "HEAD"],
                       capture_output=True, text=True)
    return r.stdout.strip() or "unknown"


def window(run: Path, steps: int, coupling: str | None = None,
           t_end: float | None = None, mesh_repair: str | None = None) -> dict:
    """Resume a copy of ``run``'s checkpoint and time ``steps`` steps (``coupling``: on
    another coupled solver than the run's; ``t_end``: past a finished run's end;
    ``mesh_repair``: another ``Scene.mesh_repair``)."""
    import skfem_granular
    from skfem_granular.simulation import Simulation

    with scratch_copy(run, "resume_window_") as folder:
        w0, c0 = time.perf_counter(), time.process_time()
        sim = Simulation.resume(folder, t_end=t_end, coupling=coupling,
                                mesh_repair=mesh_repair)
        resume = {"wall_s": time.perf_counter() - w0, "cpu_s": time.process_time() - c0,
                  "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}
        stepper = sim.stepper
        before = dict(getattr(stepper, "factor_counts", {}))
        remeshes0 = getattr(stepper, "remeshes", 0)
        repairs0 = dict(getattr(stepper, "mesh_repairs", {}))
        per_step, dofs = [], []
        w_last, c_last = time.perf_counter(), time.process_time()
        for _t, _state in sim.evolve():
            w, c = time.perf_counter(), time.process_time()
            per_step.append({"wall_s": w - w_last, "cpu_s": c - c_last})
            w_last, c_last = w, c
            dofs.append(int(stepper.space.N))
            if len(per_step) >= steps:
                break
        after = dict(getattr(stepper, "factor_counts", {}))
        return {
            "run": run.name,
            "coupling": sim.scene.coupling,
            "code": str(Path(skfem_granular.__file__).resolve().parents[1]),
            "commit": commit_of(Path(skfem_granular.__file__).resolve().parents[1]),
            "steps": len(per_step),
            "resume": resume,
            "steps_wall_s": sum(s["wall_s"] for s in per_step),
            "steps_cpu_s": sum(s["cpu_s"] for s in per_step),
            "per_step": per_step,
            "dofs": dofs,
            "remeshes": getattr(stepper, "remeshes", 0) - remeshes0,
            "mesh_repair": sim.scene.mesh_repair,
            "repairs": {k: v - repairs0.get(k, 0)
                        for k, v in getattr(stepper, "mesh_repairs", {}).items()},
            # where the grains are at the end (the same for two versions doing the same
            # arithmetic; within the run's own spread for two that do not)
            "t": float(sim.stepper.state.t),
            "grains_mean_vy": float(sim.dem.particles.v[1].mean()),
            "grains_kinetic_energy": float(0.5 * (sim.dem.mass * (
                sim.dem.particles.v[:2] ** 2).sum(axis=0)).sum()),
            "factor_counts": {k: after.get(k, 0) - before.get(k, 0) for k in after},
            "phases_s": {k: float(v) for k, v in sim.timings.items()},
            "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        }


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    run_argument(ap)
    ap.add_argument("--steps", type=int, default=12)
    ap.add_argument("--coupling", choices=["monolithic", "split"], default=None,
                    help="continue on this coupled solver (default: the run's)")
    ap.add_argument("--mesh-repair", choices=["auto", "flips", "none"], default=None,
                    help="continue with this mesh repair (default: the run's)")
    ap.add_argument("--t-end", type=float, default=None,
                    help="the resumed run's end (s), for a run that has finished")
    ap.add_argument("--out", type=Path, default=None,
                    help="JSON file the record is appended to (default: print only)")
    args = ap.parse_args(argv)
    check_run(args.run, steps=args.steps)
    rec = window(args.run, args.steps, args.coupling, args.t_end, args.mesh_repair)
    print(json.dumps({k: v for k, v in rec.items() if k not in ("per_step", "dofs")}))
    if args.out is not None:
        # a file of another form (an interleaved comparison's "calls") keeps what it holds
        data = json.loads(args.out.read_text()) if args.out.exists() else {}
        data.setdefault("benchmark", "resume_window")
        data["records"] = data.get("records", []) + [rec]
        args.out.write_text(json.dumps(data, indent=1) + "\n")


if __name__ == "__main__":
    main()
