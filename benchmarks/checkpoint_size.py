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
import shutil
import sys
import tempfile
import time
import zipfile
from contextlib import closing
from pathlib import Path


def measure(run: Path, writes: int) -> dict:
    """Resume a copy of ``run``, take one step, write its checkpoint ``writes`` times."""
    from skfem_granular.simulation import Simulation, checkpoint

    with tempfile.TemporaryDirectory(prefix="checkpoint_size_") as tmp:
        folder = Path(tmp) / run.name
        folder.mkdir()
        for name in ("checkpoint.npz", "history.csv"):
            shutil.copy2(run / name, folder / name)
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
    ap.add_argument("run", type=Path, help="a run's output folder with checkpoint.npz")
    ap.add_argument("--writes", type=int, default=3)
    ap.add_argument("--out", type=Path, default=None, help="JSON file (default: print only)")
    args = ap.parse_args(argv)
    if not (args.run / "checkpoint.npz").exists():
        sys.exit(f"run: {args.run} has no checkpoint.npz")
    if args.writes < 1:
        sys.exit(f"--writes = {args.writes}: must be at least 1")
    rec = measure(args.run, args.writes)
    print(json.dumps({k: v for k, v in rec.items() if k != "largest_members"}))
    if args.out is not None:
        args.out.write_text(json.dumps({"benchmark": "checkpoint_size", **rec}, indent=1) + "\n")


if __name__ == "__main__":
    main()
