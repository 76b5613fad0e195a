"""Benchmark: does earlier work in a process slow down the 200-grain coupled factorisation?

Usage::

    python benchmarks/factorisation_state.py [--conditions fresh,small,...] [--slow]
        [--solver auto|superlu|pardiso] [--tag NAME]

Reported (never explained): in a long-lived process that had run other sparse
factorisations and solves first, ``factors.operator(a0)`` of the monolithic coupling of
the dense 200-grain column (core ratio 0.9, dt 2e-4 s, ``a0 = 1 / dt``) ran for more
than 2.5 min and grew past 4.3 GB; in a fresh process it takes about 2 s.

Each condition is one child process (``timeout`` 300 s, killed by a watchdog above
7 GB resident) that runs a sequence of steps and then the 200-grain call; per step the
child records wall time, and for the coupled factorisation its peak resident memory
(``VmHWM`` of ``/proc/self/status``, reset through ``/proc/self/clear_refs`` right
before the call), the resident memory before it, the factors' entries, a hash of the
ordering and of the matrix pattern (to see whether earlier work changed what is
factorised) and whether a cached :class:`~skfem_granular.fluid.factor_plan.FactorPlan`
was used. Steps:

- ``mono:N``: build the N-grain column's monolithic coupling, factorise, one solve;
- ``split:N``: the N-grain split coupling's projection factorisation;
- ``run:N,S,scheme``: a short simulation of the N-grain column (S steps);
- ``pivotsp``: the threshold-pivoted SuperLU fallback on the paper's single particle;
- ``pivot:N``: the same fallback on the N-grain column (25 grains: 2 min, 1.8 GB);
- ``trim``: ``malloc_trim(0)`` (glibc);
- ``drop:N[,cycle]``: build and factorise the N-grain monolithic coupling, then drop it
  and record the resident memory before, after ``del`` (reference counting only), after
  ``gc.collect()`` and after ``malloc_trim(0)``; with ``cycle`` the solver is first put
  in a reference cycle (``solver.me = solver``), as an object kept by a cycle would be;
  with ``run`` the simulation runs 2 steps instead (what a finished run leaves behind);
- ``mkpardiso:K``: K :class:`PardisoSolver` objects made (copies of the template) and
  dropped without a factorisation;
- ``share``: from here on every monolithic coupling gets the same solver object (as a
  ``CorrectorOptions(solver=<object>)`` reused across scenes would give it);
- ``gcoff``: Python's cyclic collector disabled from here on (a process whose
  generation-2 collections are rare: big arrays count as one allocation each);
- a ``t-`` prefix runs the step in a worker thread (a study's thread pool: its own
  glibc malloc arena).

``--solver`` (recorded in the JSON; passed to the child as ``FACTORISATION_SOLVER``)
forces the linear solver of every coupling the child builds (``auto``: the library's
choice, PARDISO from ``AUTO_PARDISO_SIZE`` unknowns when pypardiso imports, i.e. at 100
and 200 grains but not at 25). ``--solver pardiso`` needs an environment with
pypardiso (not the project's ``.venv``); ``--solver pardiso`` runs the conditions of
``PARDISO_CONDITIONS`` by default and writes ``factorisation_state_pardiso.json``.

Writes ``benchmarks/results/factorisation_state.json`` (``--tag``: ``_<tag>``).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from record import commit, machine  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PACKINGS = ROOT / "benchmarks" / "results" / "packings"
TIMEOUT_S = 300
RSS_LIMIT_KB = 7_000_000

#: name -> (steps, extra environment)
CONDITIONS = {
    "fresh": (["mono:200"], {}),
    "fresh_again": (["mono:200", "mono:200"], {}),
    "small_monolithic": (["mono:25", "mono:100", "mono:200"], {}),
    "split": (["split:200", "run:25,5,split", "mono:200"], {}),
    "short_runs": (["run:25,10,monolithic", "run:25,5,split", "mono:200"], {}),
    "pivoted_small": (["pivotsp", "mono:25", "mono:200"], {}),
    "threads": (["t-pivotsp", "t-mono:25", "t-split:200", "t-run:25,5,split", "t-mono:200",
                 "mono:200"], {}),
    "threads_arena1": (["t-pivotsp", "t-mono:25", "t-split:200", "t-run:25,5,split",
                        "t-mono:200", "mono:200"], {"MALLOC_ARENA_MAX": "1"}),
    "threads_trim": (["t-pivotsp", "t-mono:25", "t-split:200", "t-run:25,5,split", "trim",
                      "t-mono:200"], {}),
}
SLOW = {"pivoted_n25": (["pivot:25", "mono:200"], {})}  # 2 min of pivoted factorisation

#: the PARDISO path (``--solver pardiso`` or ``auto`` with pypardiso installed)
PARDISO_CONDITIONS = {
    "fresh": (["mono:200"], {}),
    "fresh_again": (["mono:200", "mono:200"], {}),
    "small_monolithic": (["mono:25", "mono:100", "mono:200"], {}),
    "short_runs": (["run:25,10,monolithic", "run:100,3,monolithic", "run:25,5,split",
                    "mono:200"], {}),
    "solvers_dropped": (["mkpardiso:20", "drop:100", "drop:100", "drop:25", "mono:200"], {}),
    "solvers_cycle": (["drop:100,cycle", "drop:100,cycle", "mono:200"], {}),
    "run_dropped": (["drop:100,run", "drop:100,run", "mono:200"], {}),
    "gc_off": (["gcoff", "mono:100", "mono:100", "run:100,2,monolithic", "mono:200"], {}),
    "threads": (["t-mono:25", "t-mono:100", "t-run:25,5,split", "t-mono:200", "mono:200"],
                {}),
    "mkl_threads2": (["mono:200", "mono:200"], {"MKL_NUM_THREADS": "2",
                                                 "OMP_NUM_THREADS": "2"}),
    "shared_solver": (["share", "mono:25", "mono:100", "mono:200"], {}),
    "mkl_threads2_after": (["mono:25", "mono:100", "run:25,5,split", "mono:200"],
                           {"MKL_NUM_THREADS": "2", "OMP_NUM_THREADS": "2"}),
}


# ------------------------------------------------------------------ child
def _status() -> dict:
    out = {}
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(("VmRSS", "VmHWM")):
                k, v = line.split(":")
                out[k] = int(v.split()[0]) * 1024 / 1e9
    return out


def _reset_peak() -> bool:
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


def _digest(*arrays) -> str:
    h = hashlib.sha1()
    for a in arrays:
        h.update(memoryview(a).cast("B"))
    return h.hexdigest()[:12]


def _trim() -> int:
    import ctypes

    return int(ctypes.CDLL("libc.so.6").malloc_trim(0))


def _mkl(name):
    """A function of MKL's runtime library if PARDISO's is loaded, else None."""
    import skfem_granular.fluid.linsolve as linsolve

    tpl = linsolve._PYPARDISO_TEMPLATE
    return None if tpl is None else getattr(tpl.libmkl, name)


def _mkl_bytes() -> int | None:
    """Bytes MKL's memory manager holds (``MKL_Mem_Stat``), None without MKL loaded."""
    import ctypes

    f = _mkl("MKL_Mem_Stat")
    if f is None:
        return None
    f.restype = ctypes.c_int64
    n = ctypes.c_int(0)
    return int(f(ctypes.byref(n)))


def _mkl_threads() -> int | None:
    f = _mkl("mkl_get_max_threads")
    return None if f is None else int(f())


def _factor_info(solver) -> dict:
    """Size of the factors: SuperLU's L + U entries; PARDISO's from ``iparm`` (0-based:
    17 factor entries, 14 peak analysis memory, 15 + 16 permanent + numerical, KiB)."""
    if solver.name == "superlu":
        lu = solver._lu.lu
        return {"factor_entries": int(lu.L.nnz + lu.U.nnz)}
    if solver.name == "pardiso":
        ip = solver._solver.iparm
        return {"factor_entries": int(ip[17]), "pardiso_peak_analysis_mb": int(ip[14]) * 1.024e-3,
                "pardiso_factor_memory_mb": solver.factor_memory_mb,
                "pardiso_perturbed_pivots": int(ip[13]),
                "pardiso_analyses_reused": int(solver.analyses_reused)}
    return {}


def _child(steps: list[str]) -> None:
    import gc
    from dataclasses import replace

    import numpy as np

    import skfem_granular.fluid.superlu as superlu
    from skfem_granular.collapse import column_scene
    from skfem_granular.packing import load_packing
    from skfem_granular.simulation import Budget, Simulation

    plan_hits = []
    plan_for = superlu.plan_for

    def logged_plan_for(A, nu, perm, Mp=None):
        plan = plan_for(A, nu, perm, Mp)
        plan_hits.append(plan is not None)
        return plan

    superlu.plan_for = logged_plan_for

    forced = os.environ.get("FACTORISATION_SOLVER", "auto")
    if forced != "auto":
        import skfem_granular.coupled.monolithic as monolithic
        import skfem_granular.coupled.partitioned as partitioned
        import skfem_granular.fluid.linsolve as linsolve

        def make_forced(solver="auto", size=0, **kw):
            return linsolve.make_solver(forced if solver == "auto" else solver, size, **kw)

        monolithic.make_solver = partitioned.make_solver = make_forced

    shared = {}

    def make_shared(solver="auto", size=0, **kw):
        """One solver object for every monolithic coupling (``share`` step)."""
        import skfem_granular.fluid.linsolve as linsolve

        if "solver" not in shared:
            shared["solver"] = linsolve.make_solver(
                forced if forced != "auto" else "pardiso", size, **kw)
        return shared["solver"]

    def simulation(n, scheme, steps=1):
        pk = load_packing(PACKINGS / f"dense_a0.8_n{n}_seed0.npz")
        sc = column_scene(pk, fluid=True, core_ratio=0.9, t_end=2e-4, dt=2e-4)
        sc = replace(sc, coupling=scheme, time=replace(sc.time, t_end=steps * sc.time.dt))
        return Simulation(sc, budget=Budget(max_memory=1e12)), sc

    def single_particle():
        from skfem_granular.scene import Scene

        sc = replace(Scene.bundled("single_particle"), output_dir=None, coupling="monolithic")
        return Simulation(sc, budget=Budget(max_memory=1e12)), sc

    def step(kind: str, arg: str) -> dict:
        if kind == "mono":
            sim, sc = simulation(int(arg), "monolithic")
            c = sim.stepper.keeper.coupling
            del plan_hits[:]
            gc.collect()
            reset = _reset_peak()
            before = _status()["VmRSS"]
            t0 = time.perf_counter()
            c.factors.operator(1.0 / sc.time.dt)
            t = time.perf_counter() - t0
            peak = _status()["VmHWM"]
            rec = {"unknowns": int(c.nz), "solver": c.solver.name, "t_operator_s": t,
                   "peak_rss_gb": peak, "peak_reset": reset, "rss_before_gb": before,
                   "ordering_sha1": _digest(np.ascontiguousarray(c._ordering)),
                   "plan_used": any(plan_hits)}
            rec.update(_factor_info(c.solver), mkl_threads=_mkl_threads(),
                       mkl_bytes=_mkl_bytes())
            A = c.solver._A
            rec["pattern_sha1"] = _digest(A.indptr, A.indices)
            b = A @ np.random.default_rng(0).standard_normal(c.nz)
            t0 = time.perf_counter()
            c.solver.solve_correction(b)
            rec["t_solve_s"] = time.perf_counter() - t0
            return rec
        if kind == "drop":
            n, _, mode = arg.partition(",")
            sim, sc = simulation(int(n), "monolithic", 2 if mode == "run" else 1)
            c = sim.stepper.keeper.coupling
            t0 = time.perf_counter()
            if mode == "run":
                sim.run(progress=False)
                c = sim.stepper.keeper.coupling
            else:
                c.factors.operator(1.0 / sc.time.dt)
            rec = {"unknowns": int(c.nz), "solver": c.solver.name,
                   ("t_run_s" if mode == "run" else "t_operator_s"): time.perf_counter() - t0,
                   "mode": mode or "plain",
                   "rss_factorised_gb": _status()["VmRSS"]}
            rec.update(_factor_info(c.solver))
            rec["mkl_bytes_factorised"] = _mkl_bytes()
            if mode == "cycle":
                c.solver.me = c.solver
            del sim, sc, c
            rec["rss_after_del_gb"] = _status()["VmRSS"]
            rec["mkl_bytes_after_del"] = _mkl_bytes()
            rec["gc_collected"] = gc.collect()
            rec["rss_after_gc_gb"] = _status()["VmRSS"]
            rec["mkl_bytes_after_gc"] = _mkl_bytes()
            _trim()
            rec["rss_after_trim_gb"] = _status()["VmRSS"]
            return rec
        if kind == "mkpardiso":
            from skfem_granular.fluid.linsolve import PardisoSolver

            before = _status()["VmRSS"]
            t0 = time.perf_counter()
            for _ in range(int(arg)):
                PardisoSolver()
            return {"t_make_s": time.perf_counter() - t0, "rss_before_gb": before}
        if kind == "share":
            import skfem_granular.coupled.monolithic as monolithic

            monolithic.make_solver = make_shared
            return {"shared_solver": True}
        if kind == "gcoff":
            gc.disable()
            return {"gc_enabled": gc.isenabled()}
        if kind == "split":
            sim, sc = simulation(int(arg), "split")
            t0 = time.perf_counter()
            sim.stepper.keeper.coupling.projection.factorize()
            return {"t_projection_s": time.perf_counter() - t0}
        if kind == "run":
            n, steps, scheme = arg.split(",")
            sim, sc = simulation(int(n), scheme, int(steps))
            t0 = time.perf_counter()
            sim.run(progress=False)
            return {"status": sim.status, "t_run_s": time.perf_counter() - t0}
        if kind in ("pivot", "pivotsp"):
            sim, sc = simulation(int(arg), "monolithic") if arg else single_particle()
            c = sim.stepper.keeper.coupling
            c.factors.operator(1.0 / sc.time.dt)
            t0 = time.perf_counter()
            c.solver._pivoted()
            return {"unknowns": int(c.nz), "t_pivoted_s": time.perf_counter() - t0,
                    "pivoted_entries": int(c.solver._lu.L.nnz + c.solver._lu.U.nnz)}
        if kind == "trim":
            return {"malloc_trim": _trim()}
        raise ValueError(f"step {kind!r}")

    for s in steps:
        kind, _, arg = s.partition(":")
        t0 = time.perf_counter()
        if kind.startswith("t-"):
            from concurrent.futures import ThreadPoolExecutor

            with ThreadPoolExecutor(1) as ex:
                rec = ex.submit(step, kind[2:], arg).result()
        else:
            rec = step(kind, arg)
        rec.update(step=s, t_step_s=time.perf_counter() - t0, rss_after_gb=_status()["VmRSS"])
        print(json.dumps(rec), flush=True)


# ------------------------------------------------------------------ parent
def _versions() -> dict:
    from importlib import metadata

    out = {}
    for name in ("numpy", "scipy", "pypardiso", "mkl"):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def run_condition(steps: list[str], env_extra: dict, solver: str = "auto") -> dict:
    """One child process: its step records, exit code, watchdog verdict, largest RSS."""
    env = {**os.environ, **env_extra, "FACTORISATION_SOLVER": solver,
           "PYTHONPATH": os.pathsep.join(
        p for p in (str(ROOT), str(ROOT / "benchmarks"), os.environ.get("PYTHONPATH")) if p)}
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", *steps]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, text=True)
    largest, verdict = 0, None
    while proc.poll() is None:
        try:
            with open(f"/proc/{proc.pid}/status") as f:
                rss = next(int(line.split()[1]) for line in f if line.startswith("VmRSS"))
        except (OSError, StopIteration):
            rss = 0
        largest = max(largest, rss)
        if rss > RSS_LIMIT_KB:
            verdict = f"killed: resident {rss / 1e6:.2f} GB"
        elif time.perf_counter() - t0 > TIMEOUT_S:
            verdict = f"killed: over {TIMEOUT_S} s"
        if verdict:
            proc.kill()
            break
        time.sleep(0.25)
    out = proc.communicate()[0]
    records = [json.loads(line) for line in out.splitlines() if line.startswith("{")]
    return {"steps": steps, "env": env_extra, "returncode": proc.returncode,
            "watchdog": verdict, "largest_rss_gb": largest / 1e6,
            "wall_s": time.perf_counter() - t0, "records": records}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--conditions", default=None,
                    help="default: all of CONDITIONS (PARDISO_CONDITIONS for --solver pardiso)")
    ap.add_argument("--solver", default="auto", choices=("auto", "superlu", "pardiso"))
    ap.add_argument("--slow", action="store_true", help="also " + ", ".join(SLOW))
    ap.add_argument("--tag", default=None)
    ap.add_argument("--child", nargs="+", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        _child(args.child)
        return 0
    pardiso = args.solver == "pardiso"
    default = PARDISO_CONDITIONS if pardiso else CONDITIONS
    table = {**CONDITIONS, **SLOW, **({"p_" + k: v for k, v in PARDISO_CONDITIONS.items()})}
    if pardiso:
        table.update(PARDISO_CONDITIONS)
    names = (args.conditions.split(",") if args.conditions else list(default)) + (
        list(SLOW) if args.slow else [])
    name = "factorisation_state" + ("_pardiso" if pardiso else "") + (
        f"_{args.tag}" if args.tag else "")
    path = ROOT / "benchmarks" / "results" / f"{name}.json"
    out = {"benchmark": "factorisation_state", "commit": commit(), "machine": machine(),
           "solver": args.solver, "packages": _versions(),
           "loadavg_start": os.getloadavg(), "timeout_s": TIMEOUT_S,
           "rss_limit_gb": RSS_LIMIT_KB / 1e6, "conditions": {}}
    if path.exists() and args.tag is None and pardiso:  # conditions run one at a time
        old = json.loads(path.read_text())
        if old.get("solver") == args.solver:
            out["conditions"] = old.get("conditions", {})
    for c in names:
        steps, env = table[c]
        rec = run_condition(steps, env, args.solver)
        rec["loadavg"] = os.getloadavg()
        rec["commit"] = commit()
        last = [r for r in rec["records"] if r.get("step", "").endswith("mono:200")]
        rec["mono200"] = [{k: r.get(k) for k in (
            "solver", "t_operator_s", "peak_rss_gb", "rss_before_gb", "factor_entries",
            "pardiso_factor_memory_mb", "ordering_sha1", "pattern_sha1", "plan_used")}
            for r in last]
        out["conditions"][c] = rec
        print(c, rec["watchdog"] or f"rc {rec['returncode']}",
              [(round(r["t_operator_s"], 2), round(r["peak_rss_gb"], 3)) for r in last],
              flush=True)
        path.write_text(json.dumps(out, indent=1) + "\n")
    out["loadavg_end"] = os.getloadavg()
    path.write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
