"""Benchmark: the whole ``skfem-granular run single-particle`` process, start to exit.

Usage: ``python benchmarks/startup.py [--repeats N] [--output PATH]``.

Every measurement is a fresh process, timed from outside (wall time) with its
CPU time (user + system, from the kernel's accounting of the finished child;
less sensitive than wall time to other jobs on the shared machine):

- ``cli_cold``: ``skfem-granular run single-particle`` with an empty numba
  cache (``NUMBA_CACHE_DIR`` a new directory: every kernel the run needs is
  compiled);
- ``cli_warm``: the same run after an earlier one filled the cache (what a user
  sees from the second run of an installation on);
- ``cli_warm_no_pyc``: warm numba cache, but this package's own modules
  (``skfem_granular``, ``meshing``) compiled from source in every process
  (``PYTHONDONTWRITEBYTECODE=1`` and no bytecode of them; numpy, scipy, ... from
  their bytecode), as in a checkout whose ``__pycache__`` is not written;
- ``import``: ``python -c "import skfem_granular"``;
- ``python``: ``python -c "pass"`` (the interpreter alone).

Bytecode goes to a temporary ``PYTHONPYCACHEPREFIX`` (warmed before timing), so
the checkout is not written to; the run writes its VTU frames and summary into a
temporary ``--out`` directory. Modes are interleaved, one repeat of each in
turn, so load from other jobs spreads over all of them; the JSON records every
sample, the medians and the 1-minute load average before and after.
Writes ``benchmarks/results/startup.json``.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGET = 1.5  # s: the whole single-particle process
CLI_CODE = "import sys; from skfem_granular.cli import main; sys.exit(main())"


def _cli() -> list[str]:
    """The installed ``skfem-granular`` script next to this interpreter (else ``-c main()``)."""
    script = Path(sys.executable).parent / "skfem-granular"
    if script.exists():
        return [str(script)]
    return [sys.executable, "-c", CLI_CODE]


def timed(cmd: list[str], env: dict) -> tuple[float, float]:
    """Wall and CPU seconds of one run of ``cmd`` (which must succeed)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, cwd=ROOT, stdout=subprocess.DEVNULL,
                          stderr=subprocess.PIPE, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"{cmd} failed ({proc.returncode}): {proc.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def summary(samples: list[tuple[float, float]]) -> dict:
    wall = [w for w, _ in samples]
    cpu = [c for _, c in samples]
    return {"wall_median": statistics.median(wall), "wall_min": min(wall),
            "cpu_median": statistics.median(cpu), "wall": wall, "cpu": cpu}


#: packages whose import time the JSON records (where first imported during a run)
PROFILED = ("skfem_granular", "numpy", "scipy.sparse", "scipy.sparse.linalg", "skfem", "meshing",
            "triangle", "scipy.spatial", "numba", "meshio", "tqdm", "pyamg", "matplotlib",
            "pyvista")


def import_profile(args: list[str], env: dict) -> dict:
    """Import times (``-X importtime``) of ``python args``.

    ``total_s``: all imports; ``first_import_s``: for each of :data:`PROFILED` that was
    imported, the cumulative time of its first import (including whatever it imported
    first, so the entries overlap: ``skfem`` includes most of ``scipy.sparse``).
    """
    proc = subprocess.run([sys.executable, "-X", "importtime", *args], env=env, cwd=ROOT,
                          capture_output=True, text=True, check=True)
    total, first = 0.0, {}
    for line in proc.stderr.splitlines():
        if not line.startswith("import time:") or "self [us]" in line:
            continue
        _, cumulative, name = line[len("import time:"):].split("|", 2)
        seconds = int(cumulative) / 1e6
        if len(name) - len(name.lstrip()) == 1:  # top level: not inside another import
            total += seconds
        first.setdefault(name.strip(), seconds)
    return {"total_s": total, "first_import_s": {m: first[m] for m in PROFILED if m in first}}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--output", default=str(ROOT / "benchmarks" / "results" / "startup.json"))
    args = ap.parse_args(argv)

    with tempfile.TemporaryDirectory(prefix="skfem_granular_startup_") as tmp:
        tmp = Path(tmp)
        base = {k: v for k, v in os.environ.items()
                if k not in ("PYTHONDONTWRITEBYTECODE", "NUMBA_CACHE_DIR", "PYTHONPYCACHEPREFIX")}
        base["PYTHONPYCACHEPREFIX"] = str(tmp / "pyc")
        warm_env = dict(base, NUMBA_CACHE_DIR=str(tmp / "numba_warm"))
        out = str(tmp / "run")
        run = _cli() + ["run", "single-particle", "--out", out]

        def cold_env(k):
            return dict(base, NUMBA_CACHE_DIR=str(tmp / f"numba_cold_{k}"))

        timed(run, warm_env)  # fills the bytecode and the warm numba cache
        timed(run, warm_env)
        # the same bytecode without this package's modules, never written
        shutil.copytree(tmp / "pyc", tmp / "pyc_deps")
        for pkg in ("skfem_granular", "meshing"):
            where = Path(importlib.util.find_spec(pkg).submodule_search_locations[0])
            shutil.rmtree(tmp / "pyc_deps" / where.relative_to(where.anchor), ignore_errors=True)
        no_pyc_env = dict(warm_env, PYTHONDONTWRITEBYTECODE="1",
                          PYTHONPYCACHEPREFIX=str(tmp / "pyc_deps"))
        load_before = os.getloadavg()[0]
        samples = {m: [] for m in ("cli_cold", "cli_warm", "cli_warm_no_pyc", "import", "python")}
        for k in range(args.repeats):
            samples["cli_cold"].append(timed(run, cold_env(k)))
            samples["cli_warm"].append(timed(run, warm_env))
            samples["cli_warm_no_pyc"].append(timed(run, no_pyc_env))
            samples["import"].append(timed([sys.executable, "-c", "import skfem_granular"],
                                           warm_env))
            samples["python"].append(timed([sys.executable, "-c", "pass"], warm_env))
        load_after = os.getloadavg()[0]
        kernels = sorted(p.name for p in (tmp / "numba_warm").rglob("*.nbi"))
        with open(Path(out) / "summary.json") as f:
            run_summary = json.load(f)
        profile = {
            "import skfem_granular": import_profile(["-c", "import skfem_granular"], warm_env),
            "run single-particle": import_profile(
                ["-c", CLI_CODE, "run", "single-particle", "--out", out], warm_env)}

    import numba
    import numpy
    import scipy

    rev = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                         capture_output=True, text=True).stdout.strip()
    if subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT,
                      capture_output=True, text=True).stdout.strip():
        rev += "+uncommitted"
    result = {
        "benchmark": "startup",
        "command": "skfem-granular run single-particle --out TMP",
        "target_s": TARGET,
        "machine": platform.platform(), "cpus": os.cpu_count(),
        "python": platform.python_version(), "numpy": numpy.__version__,
        "scipy": scipy.__version__, "numba": numba.__version__, "commit": rev,
        "repeats": args.repeats,
        "load_average_1min": [load_before, load_after],
        "modes": {m: summary(s) for m, s in samples.items()},
        "numba_kernels_cached_by_the_run": kernels,
        "run_wall_time_reported_by_the_run": run_summary.get("wall_time"),
        "import_profile": profile,
    }
    Path(args.output).parent.mkdir(parents=True, exist_ok=True)
    Path(args.output).write_text(json.dumps(result, indent=2) + "\n")
    for m, s in result["modes"].items():
        print(f"{m:16s} wall median {s['wall_median']:.3f} s (min {s['wall_min']:.3f}), "
              f"cpu median {s['cpu_median']:.3f} s")
    print(f"load {load_before:.2f} -> {load_after:.2f}; numba kernels: {len(kernels)}; "
          f"target {TARGET} s; wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
