"""Benchmark: what reading a long run's history back costs when it is resumed.

Copies a run's checkpoint and history.csv into a scratch folder (the run itself is not
touched) and reads them back as a resume does (``checkpoint.load`` and the history's
``adopt``), each time in a fresh interpreter: the wall time, the peak resident memory
and how many rows hold their per-grain values in memory. With ``--baseline CHECKOUT``
the same is done with another checkout's code, in turn with this one's, ``--pairs``
times (ratios pair by pair).

Usage::

    python benchmarks/history_resume.py ~/runs/.../loose_immersed_core0.9_s0_split \\
        --baseline ~/old_checkout --out benchmarks/results/history_resume_n1000.json
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

from record import commit, machine
from run_copy import check_run, run_argument, scratch_copy

ROOT = Path(__file__).resolve().parents[1]


def child(folder: Path) -> dict:
    """Read ``folder``'s checkpoint and history as a resume does; the record."""
    from skfem_granular.io import History
    from skfem_granular.simulation import checkpoint

    t0 = time.perf_counter()
    data = checkpoint.load(folder)
    K = len(data["scene"].particles)
    hist = History(K)
    if hasattr(hist, "adopt"):
        hist.adopt(data["history"], folder / checkpoint.HISTORY_FILENAME)
    else:  # code that kept every row in memory
        hist.rows = list(data["history"])
    seconds = time.perf_counter() - t0
    return {"grains": K, "rows": len(hist.rows),
            "rows_with_values": sum("x" in r for r in hist.rows), "load_s": seconds,
            "peak_rss_MB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def measure(code: Path, folder: Path) -> dict:
    """:func:`child` in a fresh interpreter that imports the library from ``code``."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(code), str(ROOT / "benchmarks")])}
    out = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--child",
                          str(folder)], env=env, cwd=code, check=True, stdout=subprocess.PIPE,
                         text=True)
    return {"code": str(code), **json.loads(out.stdout.strip().splitlines()[-1])}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    if argv is None and sys.argv[1:2] == ["--child"]:
        print(json.dumps(child(Path(sys.argv[2]))))
        return
    run_argument(ap)
    ap.add_argument("--baseline", type=Path, default=None,
                    help="a checkout of other code, measured in turn with this one")
    ap.add_argument("--pairs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=None, help="JSON file (default: print only)")
    args = ap.parse_args(argv)
    check_run(args.run, pairs=args.pairs)
    codes = [ROOT] if args.baseline is None else [args.baseline.resolve(), ROOT]
    records = []
    with scratch_copy(args.run, "history_resume_") as folder:
        for _ in range(args.pairs):
            for code in codes:
                rec = measure(code, folder)
                print(json.dumps(rec))
                records.append(rec)
    if args.out is not None:
        result = {"benchmark": "history_resume", "commit": commit(), "machine": machine(),
                  "run": args.run.name, "records": records}
        args.out.write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
