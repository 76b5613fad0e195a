"""Fault injection for the command line: a run signalled at a random instant, and what it left.

One try launches ``skfem-granular run single-particle --t-end 3e-4`` (checkpoint every 5
steps) in a fresh folder and sends a signal after a delay drawn from ``[start, window]``
seconds (a double try sends a second one 0-50 ms later). A try passes when the process
exits with ``128 + signal`` (or is ended by the signal's default action before the
interpreter ran any of the library's code and with nothing written; or 0 when it finished
before the signal, or the signal came after the last step and the summary says
"completed"), prints no traceback, leaves no lock, and leaves its folder either untouched
(absent or empty) or resumable (a readable checkpoint, a complete history). Used by
tests/test_signals.py and benchmarks/signal_faults.py.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

LOCK = ".skfem-granular.lock"
ARGV = ["run", "single-particle", "--t-end", "3e-4", "--checkpoint-every", "5",
        "--no-progress"]


def default_sigint():
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _launch(out: Path, args=ARGV, cache=None):
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    if cache is not None:  # numba compiles every kernel anew: the longest start-up
        env["NUMBA_CACHE_DIR"] = str(cache)
    return subprocess.Popen([sys.executable, "-m", "skfem_granular.cli", *args, "--out",
                             str(out)] if "--resume" not in args else
                            [sys.executable, "-m", "skfem_granular.cli", *args],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=default_sigint)


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


def one_try(k, rng, sig, window, double, work: Path, cold: bool = False,
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
    if rec["traceback"]:  # the whole of it, to diagnose
        rec["stderr"] = err
    rec["ok"] = bool(ok_code and not rec["traceback"] and state in ("untouched", "resumable"))
    return rec


def resume_ok(out: Path) -> bool:
    proc = subprocess.run([sys.executable, "-m", "skfem_granular.cli", "run", "--resume",
                           str(out), "--no-progress"], capture_output=True, text=True,
                          timeout=300)
    return proc.returncode == 0
