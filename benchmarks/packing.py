"""Benchmark: dense and loose columns prepared with the DEM alone (time, solid fractions).

Usage: ``python benchmarks/packing.py [--n 1000] [--seeds 0 1 2] [--states dense loose]
[--aspect 0.8] [--shape ngon] [--save-dir DIR] [--tag NAME]``.

Every (state, seed) pours ``n`` grains (12-gon near-disks by default, d_mean = 1 mm,
d_max / d_min = 1.8, 2650 kg/m^3, E = 1e6 N/m) into a box sized for ``H0 / L0 =
aspect`` and waits until they rest (:func:`skfem_granular.packing.prepare_column`).
Writes ``benchmarks/results/packing_<tag>.json``: per run the wall and CPU time, the
simulated settling time, the solid fraction (shadow area in a window 2 d_max from the
walls, floor and surface), L0, H0 and the aspect reached; per state the mean and the
spread (sample standard deviation, min, max) of the solid fraction over the seeds.
``--save-dir`` also writes every packing as ``.npz``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

from skfem_granular.collapse import realisations
from skfem_granular.packing import prepare_column

RESULTS = Path(__file__).resolve().parent / "results"


def run(n, state, seed, aspect, shape, save_dir):
    cpu0, t0 = time.process_time(), time.perf_counter()
    load = os.getloadavg()[0]
    last = [0.0]

    def progress(t, vmax):
        if t - last[0] >= 0.05:
            last[0] = t
            print(f"  {state} seed {seed}: t = {t:.3f} s, max speed {vmax:.3g} m/s, "
                  f"{time.perf_counter() - t0:.0f} s", flush=True)

    p = prepare_column(n, aspect, state, shape=shape, seed=seed, progress=progress)
    row = {"n": n, "state": state, "seed": seed, "shape": shape,
           "solid_fraction": p.solid_fraction, "L0": p.width, "H0": p.height,
           "aspect": p.aspect, "settle_time_s": p.settle_time,
           "wall_time_s": time.perf_counter() - t0, "cpu_time_s": time.process_time() - cpu0,
           "load_average_1min_start": load, "window": list(p.window), "E": p.E}
    if save_dir is not None:
        row["file"] = str(p.save(Path(save_dir) / f"{state}_n{n}_a{aspect:g}_s{seed}.npz"))
    print(json.dumps(row), flush=True)
    return row



def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--states", nargs="+", default=["dense", "loose"])
    ap.add_argument("--aspect", type=float, default=0.8)
    ap.add_argument("--shape", default="ngon")
    ap.add_argument("--save-dir", default=None)
    ap.add_argument("--tag", default=None)
    a = ap.parse_args(argv)
    if a.save_dir:
        Path(a.save_dir).mkdir(parents=True, exist_ok=True)
    rows = [run(a.n, s, seed, a.aspect, a.shape, a.save_dir)
            for s in a.states for seed in a.seeds]
    out = {"benchmark": "packing", "machine": platform.platform(), "cpus": os.cpu_count(),
           "python": platform.python_version(), "target": "1000 grains in <= 900 s",
           "runs": rows,
           "solid_fraction": {s: realisations([r["solid_fraction"] for r in rows
                                                if r["state"] == s])
                              for s in a.states},
           "wall_time_s": {s: realisations([r["wall_time_s"] for r in rows
                                             if r["state"] == s])
                           for s in a.states}}
    tag = a.tag or f"n{a.n}"
    path = RESULTS / f"packing_{tag}.json"
    path.write_text(json.dumps(out, indent=1))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
