"""Scaling of the coupled collapse with the number of grains.

Collapses of n x n hexagons (n = 5, 10, 20: 25, 100 and 400 grains) that differ
only in size: the grain of the bundled ``collapse`` scene (radius 0.5 mm, 2650
kg/m^3, core at 0.8 of the shadow, spacing 1.15 mm, seeded random orientations),
its contacts, ``delta_l``, ``dt``, default mesh kind (``auto``) and mesh motion
(ALE); the paper's 20 x 10 mm box and the block's distance from the left wall
scaled by n / 5, its distance from the floor (3 mm) kept. Each run is a
subprocess of its own (its ``ru_maxrss`` is its peak memory), simulates a fixed
window (50 ms) and writes no output files (``--gc``: ``gc.collect()`` after every
step that remeshed, see :func:`simulate`). The cost per
simulated millisecond (wall and CPU time) is reported for the whole run and for
the steady part after the first :data:`WARMUP` steps (mesh building, first
factorisations, kernel loading), with the phase times of the run's summary;
growth exponents are least-squares slopes on log-log axes (:func:`fits`).

Fits, tables, the figure and the smoke self-check are in :mod:`scaling_report`.

Usage::

    python benchmarks/scaling.py                        # n = 5, 10, 20 -> results/scaling.json
    python benchmarks/scaling.py --smoke                # n = 2, 3, 6 steps (~10 s), checked
    python benchmarks/scaling.py --refit                # fits, figure from results/scaling.json

The figure (cost per simulated ms and peak memory against grains, fitted
slopes, a slope-1 guide) goes to ``docs/figures/scaling.png``.
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import resource
import subprocess
import sys
import time
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
from scaling_report import check, figure, fits, phase_table, regimes, table

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks/results"
FIGURE = ROOT / "docs/figures/scaling.png"

#: The paper's block is 5 x 5 grains in a 20 x 10 mm box, its first grain at (0.8, 3.0) mm.
BASE_N = 5
BASE_BOX = (20.0e-3, 10.0e-3)
BASE_ORIGIN = (0.8e-3, 3.0e-3)

#: Full run: block sizes and simulated windows (s). The bottom row starts 3 mm above the
#: floor in every box, so every window holds the same regimes: the block sediments for
#: ~30 ms, then grains touch each other and the floor (contacts, frequent remeshes).
FULL = {5: 0.05, 10: 0.05, 20: 0.05}
#: Smoke run: tiny blocks, a few steps of dt = 2e-4 s.
SMOKE = {2: 0.0012, 3: 0.0012}
#: Steps counted as start-up (first factorisations, kernels loaded from numba's cache).
WARMUP = {"full": 5, "smoke": 2}


def scaled_scene(n: int, t_end: float):
    """The bundled collapse with an n x n block in a box scaled by n / 5.

    The block keeps its distance from the left wall in the scaled box (0.8 mm x n / 5)
    and from the floor (3 mm: the bottom row reaches the floor at about the same time).
    For n < 5 (the smoke runs) the box is 10 mm high and the block 0.8 mm from the wall
    as in the paper.

    Parameters
    ----------
    n : int
        Grains per side of the block.
    t_end : float
        Simulated window (s).

    Returns
    -------
    Scene
        No output directory: nothing is written.
    """
    from skfem_granular.scene import Scene, bundled, grid_particles

    s = n / BASE_N
    grid = tomllib.loads(bundled("collapse").read_text())["grid"]
    grid = {**grid, "nx": n, "ny": n,
            "origin": [BASE_ORIGIN[0] * max(s, 1.0), BASE_ORIGIN[1]]}
    sc = Scene.bundled("collapse")
    return replace(sc, domain=(0.0, 0.0, BASE_BOX[0] * s, BASE_BOX[1] * max(s, 1.0)),
                   particles=tuple(grid_particles(grid)), output_dir=None,
                   time=replace(sc.time, t_end=t_end), name=f"collapse_{n}x{n}")


#: Wall time spent in Jacobian refreshes (:func:`time_refreshes`), in this process.
REFRESH_S = [0.0]


def time_refreshes() -> None:
    """Time ``MonolithicCoupling.factorize_jacobian`` (in this process, not the library).

    A refresh runs inside the corrector; its assembly and factorisation are booked under
    their names (and, up to commit 3690c80's parent 6b5cbb9 excluded, also under
    ``solve``: the library now leaves them out of ``solve`` itself). The time is
    reported as ``refresh``.
    """
    from skfem_granular.coupled.monolithic import MonolithicCoupling

    inner = MonolithicCoupling.factorize_jacobian
    if getattr(inner, "_timed", False):
        return

    def timed(self, *args, **kwargs):
        t0 = time.perf_counter()
        try:
            return inner(self, *args, **kwargs)
        finally:
            REFRESH_S[0] += time.perf_counter() - t0

    timed._timed = True
    MonolithicCoupling.factorize_jacobian = timed


def rss_mb() -> float:
    """Resident memory of this process now (MB; Linux ``/proc``, else the peak so far)."""
    try:
        pages = int(Path("/proc/self/statm").read_text().split()[1])
        return pages * os.sysconf("SC_PAGE_SIZE") / 2**20
    except (OSError, ValueError, IndexError):
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def cpu_s() -> float:
    """CPU time (user + system) of this process so far (s)."""
    u = resource.getrusage(resource.RUSAGE_SELF)
    return u.ru_utime + u.ru_stime


def counts(sim) -> dict:
    """Phase times (s) and solver counters of a running simulation, as they are now.

    ``phases`` has ``solve_exclusive`` (``solve``: since 6b5cbb9 the library leaves the
    Jacobian refreshes inside the corrector out of it, their assembly and factorisation
    are under their own names) and ``refresh``.
    """
    st = sim.stepper
    st.collect_timings()
    ph = {k: v for k, v in sim.timings.items() if k != "total"}
    ph["refresh"] = REFRESH_S[0]
    ph["solve_exclusive"] = ph.get("solve", 0.0)
    return {"phases": ph, "remeshes": st.remeshes, "cpu_s": cpu_s(), **st.factor_counts}


def mesh_size(sim) -> tuple[int, int]:
    """Vertices and DOFs of the mesh in use."""
    return int(sim.mesh.p.shape[1]), int(sim.stepper.space.N)


def difference(after: dict, before: dict) -> dict:
    """``after - before`` for every key of ``after`` (missing in ``before``: 0)."""
    return {k: round(v - before.get(k, 0.0), 6) for k, v in after.items()}


def simulate(n: int, t_end: float, warmup: int, log=None, collect: bool = False,
             scene=None) -> dict:
    """Run one scaled collapse in this process; the record of :data:`RUN_KEYS` but the load.

    Parameters
    ----------
    n, t_end
        See :func:`scaled_scene`.
    warmup : int
        Steps counted as start-up; the steady figures are those after them.
    log : file, optional
        A progress line every 10 steps.
    collect : bool
        ``gc.collect()`` after every step that remeshed (timed, inside the wall time).
        Up to commit 1e6e502 the mesh a remesh dropped sat in reference cycles (the
        space's self-reference, the coupling's factor cache holding a bound method of the
        coupling) with its sparse LU factors, which the cyclic collector freed late: the
        peak memory grew with the number of remeshes (25 grains, 50 ms, 17 remeshes: 1768
        MB resident at the end, 539 MB with the collections;
        ``results/scaling_no_gc.json``). Since then reference counting frees them.
    scene : Scene, optional
        Run this scene instead of :func:`scaled_scene` ``(n, t_end)`` (its own window).
    """
    from skfem_granular.simulation import Simulation

    time_refreshes()
    t0, c0 = time.perf_counter(), cpu_s()
    sim = Simulation(scaled_scene(n, t_end) if scene is None else scene)
    v0, d0 = mesh_size(sim)
    steps = {"wall_s": [], "dofs": [], "contacts": [], "remeshes": [], "rss_mb": []}
    mark, t_mark, w_mark = None, 0.0, t0
    gc_s, remeshed = 0.0, 0
    tick = time.perf_counter()
    for t, _ in sim.evolve(progress=False):
        if collect and sim.stepper.remeshes != remeshed:
            t1 = time.perf_counter()
            gc.collect()
            gc_s += time.perf_counter() - t1
        remeshed = sim.stepper.remeshes
        now = time.perf_counter()
        steps["wall_s"].append(round(now - tick, 5))
        steps["dofs"].append(mesh_size(sim)[1])
        steps["contacts"].append(int(sim.dem.contact_count().sum()))
        steps["remeshes"].append(sim.stepper.remeshes)
        steps["rss_mb"].append(round(rss_mb(), 1))
        if sim.steps_done == warmup:
            mark, t_mark, w_mark = counts(sim), t, time.perf_counter()
        if log is not None and sim.steps_done % 10 == 0:
            print(f"n={n} step {sim.steps_done} t={t:.4f} wall={now - t0:.1f}s "
                  f"dofs={steps['dofs'][-1]} remeshes={steps['remeshes'][-1]} "
                  f"contacts={steps['contacts'][-1]}", file=log, flush=True)
        tick = time.perf_counter()
    wall = time.perf_counter() - t0
    h = sim.result.history
    end = counts(sim)
    if mark is None:  # fewer steps than the warm-up: no steady part
        mark, t_mark, w_mark = end, float(h.t[-1]), t0 + wall
    rec = record(n, sim, wall, wall - (w_mark - t0), (float(h.t[-1]) - t_mark) * 1e3,
                 (mark, end), (v0, d0), steps, warmup)
    cpu = end["cpu_s"] - c0
    steady_cpu = end["cpu_s"] - mark["cpu_s"]
    return {**rec, "gc_after_remesh": collect, "gc_s": gc_s, "cpu_s": cpu,
            "steady_cpu_s": steady_cpu,
            "steady_cpu_per_ms_s": steady_cpu / rec["steady_sim_ms"] if rec["steady_sim_ms"] > 0
            else None}


def record(n, sim, wall, steady, steady_ms, marks, initial, steps, warmup) -> dict:
    """The figures of one run (see :func:`simulate`)."""
    s, h = sim.result.summary, sim.result.history
    mark, end = marks
    dofs = [initial[1], *steps["dofs"]]
    contacts = steps["contacts"]
    return {
        "n": n, "grains": sim.dem.n, "t_end": float(h.t[-1]), "steps": len(h),
        "warmup_steps": warmup, "vertices_initial": initial[0],
        "vertices_final": mesh_size(sim)[0], "dofs_initial": initial[1], "dofs_final": dofs[-1],
        "dofs_max": max(dofs), "dofs_mean": float(np.mean(dofs)), "remeshes": s["remeshes"],
        "remesh_reasons": s["remesh_reasons"], "factorizations": s.get("factorizations"),
        "jacobian_refreshes": s.get("jacobian_refreshes"), "retries": s["retries"],
        "euler_steps_at_contacts": s["euler_steps_at_contacts"],
        "max_contacts": max(contacts, default=0),
        "contacts_final": contacts[-1] if contacts else 0,
        "first_contact_step": next((k + 1 for k, c in enumerate(contacts) if c), None),
        "wall_s": wall, "startup_s": wall - steady, "steady_s": steady,
        "steady_sim_ms": steady_ms, "cost_per_ms_s": wall / (float(h.t[-1]) * 1e3),
        "steady_cost_per_ms_s": steady / steady_ms if steady_ms > 0 else None,
        "phases_s": {**s["wall_time"], **{k: round(end["phases"][k], 6)
                                          for k in ("refresh", "solve_exclusive")}},
        "steady_phases_s": difference(end["phases"], mark["phases"]),
        "steady_remeshes": end["remeshes"] - mark["remeshes"],
        "steady_factorizations": end.get("factorizations", 0) - mark.get("factorizations", 0),
        "steady_jacobian_refreshes": (end.get("jacobian_refreshes", 0)
                                      - mark.get("jacobian_refreshes", 0)),
        "iterations": int(np.sum(h.iterations)),
        "steady_iterations": int(np.sum(h.iterations[warmup:])),
        "status": s["status"], "warnings": s["warnings"],
        "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "per_step": steps,
    }


def run_child(n: int, t_end: float, warmup: int, collect: bool = False) -> dict:
    """:func:`simulate` in a fresh interpreter (its own peak memory), with the load around it."""
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", str(n), str(t_end),
           str(warmup), *(["--gc"] if collect else [])]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)}
    load0 = list(os.getloadavg())
    out = subprocess.run(cmd, check=True, stdout=subprocess.PIPE, text=True, env=env)
    rec = json.loads(out.stdout.strip().splitlines()[-1])
    rec["loadavg_before"], rec["loadavg_after"] = load0, list(os.getloadavg())
    return rec


def commit_id() -> str | None:
    """Short hash of the checkout's HEAD (None outside git)."""
    try:
        return subprocess.run(["git", "-C", str(ROOT), "log", "-1", "--format=%h"],
                              capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None


def main(argv=None) -> dict | None:
    """Command line (see the module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--smoke", action="store_true", help="n = 2, 3, a few steps")
    ap.add_argument("--n", type=int, nargs="+", help="block sizes (default 5 10 20)")
    ap.add_argument("--t-end", type=float, nargs="+",
                    help="windows (s), one for all or one per n")
    ap.add_argument("--out", type=Path, help="results JSON (default results/scaling[_smoke])")
    ap.add_argument("--figure", type=Path, help=f"figure (default {FIGURE.relative_to(ROOT)}; "
                                                "smoke: none)")
    ap.add_argument("--refit", action="store_true",
                    help="no runs: regimes, fits and figure again from the results JSON")
    ap.add_argument("--no-figure", action="store_true")
    ap.add_argument("--gc", action="store_true",
                    help="gc.collect() after every remesh (see simulate)")
    ap.add_argument("--child", nargs=3, metavar=("N", "T_END", "WARMUP"), help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        rec = simulate(int(a.child[0]), float(a.child[1]), int(a.child[2]), log=sys.stderr,
                       collect=a.gc)
        print(json.dumps(rec))
        return None
    mode = "smoke" if a.smoke else "full"
    out = a.out or RESULTS / ("scaling_smoke.json" if a.smoke else "scaling.json")
    fig = None if a.no_figure else a.figure or (None if a.smoke else FIGURE)
    if a.refit:
        data = json.loads(out.read_text())
    else:
        plan = dict(SMOKE if a.smoke else FULL)
        if a.n:
            plan = {n: plan.get(n, max(plan.values())) for n in a.n}
        if a.t_end:
            ends = a.t_end * len(plan) if len(a.t_end) == 1 else a.t_end
            plan = dict(zip(plan, ends, strict=True))
        data = {"benchmark": "scaling", "mode": mode, "commit": commit_id(),
                "cpus": os.cpu_count(), "runs": []}
        for n, t_end in plan.items():
            data["runs"].append(run_child(n, t_end, WARMUP[mode], collect=a.gc))
            out.parent.mkdir(parents=True, exist_ok=True)
            out.write_text(json.dumps(data, indent=1) + "\n")  # kept after every run
    for r in data["runs"]:
        r["regimes"] = regimes(r)
    data["fits"] = fits(data["runs"])
    out.write_text(json.dumps(data, indent=1) + "\n")
    if a.smoke:
        check(data)
    if fig is not None:
        other = RESULTS / "scaling_no_gc.json"
        no_gc = json.loads(other.read_text()) if other.exists() and not a.smoke else None
        figure(data, fig, no_gc if no_gc is not data else None)
    print(table(data))
    print(phase_table(data))
    print(json.dumps(data["fits"], indent=1))
    return data


if __name__ == "__main__":
    main()
