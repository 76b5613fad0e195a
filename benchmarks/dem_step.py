"""Benchmark: DEM steps per second for polygons settling in a box.

Usage: ``python benchmarks/dem_step.py [--quick] [--steps N] [--settle-time T]``.
Polygons fall from a square grid in a closed box for ``T`` simulated seconds
(default 0.1 s, the pile is then mostly in contact), then ``N`` steps are
timed three ways: ``DEMSystem.advance`` over 50 substeps at a time (the compiled
substep loop, as a coupled step calls it: ``"advance"``), ``DEMSystem.step`` one
step per call with the numba overlap kernel (``"numba"``) and, ``N/10`` steps, with
the pure-numpy one (``"numpy"``).
Writes ``benchmarks/results/dem_step.json`` (steps/s for 100 and 1000
polygons with 6-12 vertices), per wall-clock second and per CPU second of
this process (the single-threaded rate, insensitive to other jobs on the
machine), with the 1-minute load average at the start of the window.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from skfem_granular.dem import ContactLaw, DEMSystem, Particle, Polygon, overlap_numba


def settling_scene(n: int, seed: int = 0, backend: str = "auto") -> DEMSystem:
    """``n`` random 6-12-gons (radius 0.4-0.5 mm) on a square grid in a box.

    The grid pitch equals the largest diameter, so contacts start at once.
    """
    rng = np.random.default_rng(seed)
    r = 0.5e-3
    cols = int(np.ceil(np.sqrt(n)))
    rows = int(np.ceil(n / cols))
    pitch = 2.0 * r
    width, height = cols * pitch, rows * pitch * 1.02
    parts = []
    for k in range(n):
        cx = (k % cols + 0.5) * pitch
        cy = (k // cols + 0.5) * pitch * 1.02
        parts.append(Particle(Polygon.regular(int(rng.integers(6, 13)),
                                              rng.uniform(0.8, 1.0) * r, center=(cx, cy),
                                              angle=rng.uniform(0, 2 * np.pi)),
                              density=2650.0,
                              velocity=rng.normal(0.0, 0.01, 2)))
    law = ContactLaw(E=1e7, mu=0.3, gamma=0.3)
    return DEMSystem.in_box(parts, (0.0, 0.0, width, height), 0.5e-3, law=law,
                            backend=backend)


def time_steps(s: DEMSystem, steps: int, backend: str) -> dict:
    """Steps/s of ``steps`` steps of ``s``: ``backend`` ``"numba"`` or ``"numpy"`` (one
    :meth:`~DEMSystem.step` per call), or ``"advance"`` (:meth:`~DEMSystem.advance` over
    50 steps at a time, numba)."""
    s.backend = "numba" if backend == "advance" else backend
    builds = s.neighbours.builds
    load = os.getloadavg()[0]
    t0, c0 = time.perf_counter(), time.process_time()
    if backend == "advance":
        for _ in range(steps // 50):
            s.advance(50 * s.dt)
        steps = steps // 50 * 50
    else:
        for _ in range(steps):
            s.step()
    el, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"particles": s.n, "backend": backend, "steps": steps, "seconds": el,
            "steps_per_second": steps / el, "cpu_seconds": cpu,
            "steps_per_cpu_second": steps / cpu, "load_average_1min": load,
            "contacts": int(s.contacts.i.size),
            "dt": s.dt, "simulated_time": s.t,
            "verlet_rebuilds_in_window": s.neighbours.builds - builds}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--settle-time", type=float, default=0.1,
                    help="simulated settling time before timing (s)")
    ap.add_argument("--quick", action="store_true", help="smoke mode: few steps")
    ap.add_argument("--output", default=str(Path(__file__).parent / "results" / "dem_step.json"))
    args = ap.parse_args(argv)
    steps, settle_time = (50, 1e-5) if args.quick else (args.steps, args.settle_time)
    backends = ["advance", "numba", "numpy"] if overlap_numba.AVAILABLE else ["numpy"]
    results = []
    for n in (100, 1000):
        s = settling_scene(n, backend="numba" if overlap_numba.AVAILABLE else "numpy")
        t0 = time.perf_counter()
        while s.t < settle_time:  # settle the fastest way, then time each
            s.advance(50 * s.dt)
        settle_seconds = time.perf_counter() - t0
        for b in backends:
            res = time_steps(s, steps if b != "numpy" else max(steps // 10, 2), b)
            res["settle_steps"] = s.steps - res["steps"]
            res["settle_seconds"] = settle_seconds
            print(f"{n:5d} polygons, {b:7s}: {res['steps_per_second']:8.1f} steps/s wall, "
                  f"{res['steps_per_cpu_second']:8.1f} per CPU second "
                  f"({res['contacts']} contacts, t = {res['simulated_time']:.4f} s, "
                  f"load {res['load_average_1min']:.1f})")
            results.append(res)
    out = {"benchmark": "dem_step", "machine": platform.platform(),
           "cpus": os.cpu_count(), "python": platform.python_version(),
           "target": ">= 200 steps/s for 1000 polygons", "results": results}
    if not args.quick:
        Path(args.output).parent.mkdir(parents=True, exist_ok=True)
        Path(args.output).write_text(json.dumps(out, indent=2) + "\n")
    return out


if __name__ == "__main__":
    main()
