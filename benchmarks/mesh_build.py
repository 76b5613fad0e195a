"""Benchmark: mesh build times (medians) for the paper's box and a 100-particle group.

Usage: ``python benchmarks/mesh_build.py [--quick] [--repeat N]``. Writes
``benchmarks/results/mesh_build.json`` with median/min seconds, vertex and P2
node counts and quality figures for: graded and uniform meshes of the paper's
single-particle box (3 x 11 mm, 1 mm disk, 24 and 48 outline segments), a
100-particle group with graded surroundings, and remeshing after a move
(compared with building anew).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

import meshing

BOX = (0.0, 0.0, 3e-3, 11e-3)
GROUP_BOX = (0.0, 0.0, 10e-3, 30e-3)


def regular(n, r=0.5e-3, c=(1.5e-3, 5.5e-3), rot=0.0):
    th = rot + 2.0 * np.pi * np.arange(n) / n
    return np.vstack([c[0] + r * np.cos(th), c[1] + r * np.sin(th)])


def group(dy=0.0, rot=0.0):
    """10 x 10 lattice of 12-gons (radius 0.2 mm, pitch 0.5 mm)."""
    rng = np.random.default_rng(0)
    return [regular(12, 0.2e-3, (5e-3 + (i - 4.5) * 0.5e-3, 7.75e-3 + dy + j * 0.5e-3),
                    rng.uniform(0, 1) + rot) for i in range(10) for j in range(10)]


def timed(fn, repeat):
    fn()                                   # warm-up (imports, caches)
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - t0)
    return out, float(np.median(ts)), float(np.min(ts))


def paired(fa, fb, repeat):
    """Median seconds of two functions timed alternately (same load for both)."""
    fa(), fb()
    ta, tb = [], []
    for _ in range(repeat):
        for fn, ts in ((fa, ta), (fb, tb)):
            t0 = time.perf_counter()
            fn()
            ts.append(time.perf_counter() - t0)
    return float(np.median(ta)), float(np.median(tb))


def record(name, fn, repeat, target=None):
    mesh, med, lo = timed(fn, repeat)
    s = meshing.mesh_stats(mesh)
    res = {"case": name, "median_s": med, "min_s": lo, "repeat": repeat,
           "n_vertices": s.n_vertices, "n_p2_nodes": s.n_p2_nodes,
           "n_triangles": s.n_triangles, "min_angle_deg": s.min_angle,
           "max_aspect": s.max_aspect, "size_ratio": s.size_ratio}
    if target is not None:
        res["target_s"] = target
        res["met"] = bool(med <= target)
    print(f"{name:44s} {1e3 * med:8.1f} ms  V={s.n_vertices:6d} P2={s.n_p2_nodes:7d} "
          f"min angle {s.min_angle:5.1f}  max R/2r {s.max_aspect:4.2f}")
    return res, mesh


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--quick", action="store_true", help="smoke mode: one run each, no file")
    ap.add_argument("--output",
                    default=str(Path(__file__).parent / "results" / "mesh_build.json"))
    args = ap.parse_args(argv)
    rep = 1 if args.quick else args.repeat
    few = 1 if args.quick else max(3, rep // 3)
    d24, d48 = regular(24), regular(48)
    moved24 = regular(24, c=(1.5e-3, 4.5e-3), rot=0.3)
    results = []
    r, g24 = record("graded, paper box, 24 segments", lambda: meshing.graded_mesh(BOX, [d24]),
                    rep, 0.05)
    results.append(r)
    results.append(record("graded, paper box, 48 segments",
                          lambda: meshing.graded_mesh(BOX, [d48]), rep)[0])
    results.append(record("uniform, paper box, 24 segments (h = 0.1305 mm)",
                          lambda: meshing.uniform_mesh(BOX, [d24]), rep, 0.5)[0])
    results.append(record("uniform, paper box, 48 segments (h = 0.0654 mm)",
                          lambda: meshing.uniform_mesh(BOX, [d48]), few)[0])
    r, grp = record("group, 100 particles, graded surroundings",
                    lambda: meshing.group_mesh(GROUP_BOX, group()), few, 2.0)
    results.append(r)
    # remeshing after a move versus building anew with the moved outlines
    moved = meshing.move_particles(g24, [moved24])
    r_new = record("graded 24: build anew after move", lambda: meshing.graded_mesh(BOX, [moved24]),
                   rep)[0]
    r_re = record("graded 24: remesh after move", lambda: meshing.remesh(moved, [moved24]), rep)[0]
    new_s, re_s = paired(lambda: meshing.graded_mesh(BOX, [moved24]),
                         lambda: meshing.remesh(moved, [moved24]), rep)
    r_re.update(paired_build_s=new_s, paired_remesh_s=re_s, remesh_over_build=re_s / new_s)
    _, t_check, _ = timed(lambda: (meshing.remesh_needed(
        meshing.move_particles(g24, [moved24]))), rep)
    r_re["move_and_check_median_s"] = t_check
    gmoved = group(dy=-0.5e-3, rot=0.2)
    grp_moved = meshing.move_particles(grp, gmoved)
    g_new = record("group 100: build anew after move",
                   lambda: meshing.group_mesh(GROUP_BOX, gmoved), few)[0]
    g_re = record("group 100: remesh after move", lambda: meshing.remesh(grp_moved, gmoved),
                  few)[0]
    new_s, re_s = paired(lambda: meshing.group_mesh(GROUP_BOX, gmoved),
                         lambda: meshing.remesh(grp_moved, gmoved), few)
    g_re.update(paired_build_s=new_s, paired_remesh_s=re_s, remesh_over_build=re_s / new_s)
    print(f"paired medians, group 100: build {1e3 * new_s:.1f} ms, remesh {1e3 * re_s:.1f} ms")
    results += [r_new, r_re, g_new, g_re]
    print(f"paired medians, graded 24: build {1e3 * r_re['paired_build_s']:.1f} ms, remesh "
          f"{1e3 * r_re['paired_remesh_s']:.1f} ms")
    print(f"move_particles + remesh_needed (graded 24): {1e3 * t_check:.2f} ms")
    out = {"benchmark": "mesh_build", "machine": platform.platform(),
           "cpus": os.cpu_count(), "python": platform.python_version(),
           "numpy": np.__version__,
           "targets": {"graded single particle": "<= 0.05 s", "uniform paper box": "<= 0.5 s",
                       "group of 100": "<= 2 s", "remesh": "<= build anew (same construction)"},
           "note": "medians of --repeat runs after one warm-up; remeshing rebuilds with the "
                   "mesh's recipe, so its time equals a new build; paired_* time build and "
                   "remesh alternately so that machine load affects both alike",
           "results": results}
    if not args.quick:
        Path(args.output).parent.mkdir(parents=True, exist_ok=True)
        Path(args.output).write_text(json.dumps(out, indent=2) + "\n")
        print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
