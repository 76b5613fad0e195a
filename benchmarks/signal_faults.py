"""Benchmark: SIGTERM/SIGINT at random instants of a run's life, start-up included.

Usage: ``python benchmarks/signal_faults.py [--tries 200] [--double 50] [--signal SIGTERM]
[--window 3.0] [--seed 0] [--cold] [--tag NAME]``.

Each try launches ``skfem-granular run single-particle --t-end 3e-4`` (checkpoint every 5
steps) in a fresh folder and sends the signal after a delay drawn uniformly from
``[0, window]`` seconds (a double try sends a second one 0-50 ms later). Start-up (imports,
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
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results"
LOCK = ".skfem-granular.lock"
ARGV = ["run", "single-particle", "--t-end", "3e-4", "--checkpoint-every", "5",
        "--no-progress"]


def _default_sigint():
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _launch(out: Path, args=ARGV, cache=None):
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    if cache is not None:  # numba compiles every kernel anew: the longest start-up
        env["NUMBA_CACHE_DIR"] = str(cache)
    return subprocess.Popen([sys.executable, "-m", "skfem_granular.cli", *args, "--out",
                             str(out)] if "--resume" not in args else
                            [sys.executable, "-m", "skfem_granular.cli", *args],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_default_sigint)


def _folder_state(out: Path) -> str:
    """"untouched", "resumable", or what is wrong with the folder."""
    from skfem_granular.simulation import checkpoint

    if not out.exists() or not any(out.iterdir()):
        return "untouched"
    names = {p.name for p in out.iterdir()}
    if LOCK in names:
        return "stale lock"
    if "checkpoint.npz" not in names:
        return "written, no checkpoint: " + ",".join(sorted(names))
    try:
        checkpoint.load(out)
    except Exception as exc:  # noqa: BLE001 - any failure to read is the finding
        return f"checkpoint unreadable: {type(exc).__name__}"
    if (out / "history.csv").exists() and not (out / "history.csv").read_text().endswith("\n"):
        return "torn history"
    return "resumable"


def _send(proc, sig, delay: float, second) -> tuple[int, float]:
    """The signal after ``delay`` s (again ``second`` s later); how many were sent, and
    the wall-clock time of the first."""
    time.sleep(delay)
    sent, first = 0, time.time()
    for wait in (0.0, second):
        if wait is None or proc.poll() is not None:
            break
        time.sleep(wait)
        proc.send_signal(sig)
        sent += 1
    return sent, first


def _after_the_end(out: Path, sent_at: float) -> bool:
    """Whether the run had completed its steps when the signal came: its summary says
    "completed" and its last checkpoint (written after the last step: 30 steps, one every
    5) is older than the signal."""
    summary, ck = out / "summary.json", out / "checkpoint.npz"
    return (summary.exists() and json.loads(summary.read_text()).get("status") == "completed"
            and ck.exists() and ck.stat().st_mtime <= sent_at)


def _one_try(k, rng, sig, window, double, work: Path, cold: bool = False,
             start: float = 0.0) -> dict:
    out = work / f"try{k:04d}"
    delay = float(rng.uniform(start, window))
    second = float(rng.uniform(0.0, 0.05)) if double else None
    t0 = time.monotonic()
    proc = _launch(out, cache=work / f"cache{k:04d}" if cold else None)
    sent, sent_at = _send(proc, sig, delay, second)
    try:
        _, err = proc.communicate(timeout=300)
    except subprocess.TimeoutExpired:
        proc.kill()
        _, err = proc.communicate()
    code = proc.returncode
    state = _folder_state(out)
    # a signal that came after the last step leaves a whole run: exit 0, "completed"
    after_end = bool(sent and code == 0 and _after_the_end(out, sent_at))
    # -sig: the signal's default action, before the interpreter ran any of the library's code
    stopped = code == 128 + sig or (code == -sig and state == "untouched")
    ok_code = (stopped or after_end) if sent else code == 0
    rec = {"try": k, "delay_s": delay, "second_after_s": second, "signals_sent": sent,
           "exit": code, "elapsed_s": time.monotonic() - t0, "folder": state,
           "after_the_last_step": after_end, "traceback": "Traceback" in err,
           "stderr_lines": len(err.strip().splitlines()),
           "stderr_tail": err.strip().splitlines()[-1:] if err.strip() else []}
    rec["ok"] = bool(ok_code and not rec["traceback"] and state in ("untouched", "resumable"))
    return rec


def _resume_ok(out: Path) -> bool:
    proc = subprocess.run([sys.executable, "-m", "skfem_granular.cli", "run", "--resume",
                           str(out), "--no-progress"], capture_output=True, text=True,
                          timeout=300)
    return proc.returncode == 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tries", type=int, default=200)
    ap.add_argument("--double", type=int, default=50)
    ap.add_argument("--signal", default="SIGTERM", choices=["SIGTERM", "SIGINT"])
    ap.add_argument("--window", type=float, default=3.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--tag", default=None)
    ap.add_argument("--cold", action="store_true",
                    help="an empty numba cache for every try: the kernels compile at start-up")
    a = ap.parse_args(argv)
    if a.tries < 0 or a.double < 0 or not 0 < a.window <= 60:
        ap.error("--tries and --double must be >= 0, --window in (0, 60]")
    sig = getattr(signal, a.signal)
    rng = np.random.default_rng(a.seed)
    records = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        subprocess.run([sys.executable, "-m", "skfem_granular.cli", *ARGV, "--out",
                        str(work / "warm")], capture_output=True, check=True)  # kernel cache
        for k in range(a.tries + a.double):
            rec = _one_try(k, rng, sig, a.window, k >= a.tries, work, a.cold)
            if rec["ok"] and rec["folder"] == "resumable" and k % 10 == 0:
                rec["resumed"] = _resume_ok(work / f"try{k:04d}")
                rec["ok"] = rec["resumed"]
            records.append(rec)
            print(json.dumps(rec), flush=True)
    failed = [r for r in records if not r["ok"]]
    res = {"benchmark": "signal_faults", "signal": a.signal, "window_s": a.window,
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
