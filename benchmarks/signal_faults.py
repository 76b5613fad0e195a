"""Benchmark: SIGTERM/SIGINT at random instants of a run's life, start-up included.

Usage: ``python benchmarks/signal_faults.py [--tries 200] [--double 50] [--signal SIGTERM]
[--window 3.0] [--start 0.0] [--seed 0] [--cold] [--tag NAME]``.

Each try (``tests/fault_injection.py``, the harness the tests use) launches
``skfem-granular run single-particle --t-end 3e-4`` (checkpoint every 5 steps) in a fresh
folder and sends the signal after a delay drawn uniformly from ``[start, window]``
seconds (a double try sends a second one 0-50 ms later). Start-up (imports,
reading the scene, meshing, loading the compiled kernels) and the first steps all fall
inside the window; with ``--cold`` every try starts with an empty numba cache, so the
kernels compile during start-up (a first run's case, several seconds). A try passes when
the process exits with ``128 + signal`` (or is ended by the signal's default action, which
a shell also reports as ``128 + signal``, before the interpreter ran any of the library's
code and with nothing written; or 0 when it finished before the signal, or the signal came
after the last step and the summary says "completed"), prints no traceback, leaves no
lock, and leaves its folder
either untouched (absent or empty) or resumable (a readable checkpoint, a complete
history; every tenth such folder is resumed to the end to prove it). Writes
``benchmarks/results/signal_faults_<tag>.json``: every try (delay, exit code, what was
found) and the counts.
"""

from __future__ import annotations

import argparse
import json
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results"
# the harness the tests use (tests/fault_injection.py)
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from fault_injection import ARGV, one_try, resume_ok  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tries", type=int, default=200)
    ap.add_argument("--double", type=int, default=50)
    ap.add_argument("--signal", default="SIGTERM", choices=["SIGTERM", "SIGINT"])
    ap.add_argument("--window", type=float, default=3.0)
    ap.add_argument("--start", type=float, default=0.0,
                    help="earliest delay (s): SIGINT in the interpreter's own first "
                         "hundredths of a second is Python's KeyboardInterrupt")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--tag", default=None)
    ap.add_argument("--cold", action="store_true",
                    help="an empty numba cache for every try: the kernels compile at start-up")
    a = ap.parse_args(argv)
    if a.tries < 0 or a.double < 0 or not 0 < a.window <= 60 or not 0 <= a.start < a.window:
        ap.error("--tries and --double must be >= 0, --window in (0, 60], --start in "
                 "[0, window)")
    sig = getattr(signal, a.signal)
    rng = np.random.default_rng(a.seed)
    records = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        subprocess.run([sys.executable, "-m", "skfem_granular.cli", *ARGV, "--out",
                        str(work / "warm")], capture_output=True, check=True)  # kernel cache
        for k in range(a.tries + a.double):
            rec = one_try(k, rng, sig, a.window, k >= a.tries, work, a.cold, a.start)
            if rec["ok"] and rec["folder"] == "resumable" and k % 10 == 0:
                rec["resumed"] = resume_ok(work / f"try{k:04d}")
                rec["ok"] = rec["resumed"]
            records.append(rec)
            print(json.dumps(rec), flush=True)
    failed = [r for r in records if not r["ok"]]
    res = {"benchmark": "signal_faults", "signal": a.signal, "window_s": a.window,
           "start_s": a.start,
           "cold_numba_cache": a.cold,
           "tries": a.tries, "double": a.double, "seed": a.seed, "failed": len(failed),
           "lost": sum(r["signals_sent"] > 0 and r["exit"] == 0 and not r["after_the_last_step"]
                       for r in records),
           "tracebacks": sum(r["traceback"] for r in records),
           "folders": {s: sum(r["folder"] == s for r in records)
                       for s in sorted({r["folder"] for r in records})},
           "exits": {str(c): sum(r["exit"] == c for r in records)
                     for c in sorted({r["exit"] for r in records})},
           "commit": subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True,
                                    text=True, cwd=Path(__file__).parent).stdout.strip(),
           "runs": records}
    tag = a.tag or a.signal.lower()
    out = RESULTS / f"signal_faults_{tag}.json"
    out.write_text(json.dumps(res, indent=1))
    print(f"{len(failed)} of {len(records)} failed; wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
