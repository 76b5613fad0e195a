"""Benchmark: DEM steps per second for polygons settling in a box.

Usage: ``python benchmarks/dem_step.py [--quick] [--steps N]``. Writes
``benchmarks/results/dem_step.json`` with steps/s for 100 and 1000 polygons
(6-12 vertices) and both overlap backends (numba, numpy).
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
    """``n`` random 6-12-gons (radius 0.4-0.5 mm) on a loose grid in a box."""
    rng = np.random.default_rng(seed)
    r = 0.5e-3
    cols = int(np.ceil(np.sqrt(n)))
    rows = int(np.ceil(n / cols))
    pitch = 2.05 * r
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


def measure(n: int, steps: int, backend: str, settle: int) -> dict:
    """Steps/s after ``settle`` warm-up steps (particles in contact)."""
    s = settling_scene(n, backend=backend)
    for _ in range(settle):
        s.step()
    t0 = time.perf_counter()
    for _ in range(steps):
        s.step()
    el = time.perf_counter() - t0
    return {"particles": n, "backend": backend, "steps": steps,
            "seconds": el, "steps_per_second": steps / el,
            "contacts": int(s.contacts.i.size), "dt": s.dt,
            "verlet_rebuilds": s.neighbours.builds}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--settle", type=int, default=2000)
    ap.add_argument("--quick", action="store_true", help="smoke mode: few steps")
    ap.add_argument("--output", default=str(Path(__file__).parent / "results" / "dem_step.json"))
    args = ap.parse_args(argv)
    steps, settle = (5, 5) if args.quick else (args.steps, args.settle)
    backends = ["numba", "numpy"] if overlap_numba.AVAILABLE else ["numpy"]
    results = []
    for n in (100, 1000):
        for b in backends:
            res = measure(n, steps if b == "numba" else max(steps // 4, 2), b, settle)
            print(f"{n:5d} polygons, {b:5s}: {res['steps_per_second']:8.1f} steps/s "
                  f"({res['contacts']} contacts)")
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
