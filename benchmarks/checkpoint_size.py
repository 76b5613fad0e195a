"""Benchmark: what a run's checkpoint weighs and how long it takes to write.

Copies a run's checkpoint and history.csv into a scratch folder (the run itself is not
touched), resumes it there for one step and writes its checkpoint ``--writes`` times
(:func:`skfem_granular.simulation.checkpoint.save`, fsynced, as a run writes one),
recording the file's size, each write's wall time and the largest arrays in it.

Usage::

    python benchmarks/checkpoint_size.py out/collapse_matrix_n1000/loose_immersed_core0.9_s0 \\
        --out benchmarks/results/checkpoint_size_n1000.json
"""

from __future__ import annotations

import argparse
import json
import time
import zipfile
from contextlib import closing
from pathlib import Path

from run_copy import check_run, run_argument, scratch_copy


def measure(run: Path, writes: int) -> dict:
    """Resume a copy of ``run``, take one step, write its checkpoint ``writes`` times."""
    from skfem_granular.simulation import Simulation, checkpoint

    with scratch_copy(run, "checkpoint_size_") as folder:
        sim = Simulation.resume(folder, t_end=1.0)
        with closing(sim.evolve(progress=False)) as steps:
            next(steps)
            k = len(sim.history)
            times = []
            for _ in range(writes):
                t0 = time.perf_counter()
                checkpoint.save(sim, k, None)
                times.append(time.perf_counter() - t0)
        path = folder / "checkpoint.npz"
        with zipfile.ZipFile(path) as zf:
            members = sorted(((i.file_size, i.filename) for i in zf.infolist()), reverse=True)
        return {"run": run.name, "step": k, "grains": sim.dem.n,
                "dofs": int(sim.stepper.space.N), "bytes": path.stat().st_size,
                "write_s": times,
                "largest_members": [{"name": n, "bytes": s} for s, n in members[:12]]}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    run_argument(ap)
    ap.add_argument("--writes", type=int, default=3)
    ap.add_argument("--out", type=Path, default=None, help="JSON file (default: print only)")
    args = ap.parse_args(argv)
    check_run(args.run, writes=args.writes)
    rec = measure(args.run, args.writes)
    print(json.dumps({k: v for k, v in rec.items() if k != "largest_members"}))
    if args.out is not None:
        args.out.write_text(json.dumps({"benchmark": "checkpoint_size", **rec}, indent=1) + "\n")


if __name__ == "__main__":
    main()
