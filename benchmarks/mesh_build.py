"""Benchmark: mesh build times (medians) for the paper's box and a 100-particle group.

Usage: ``python benchmarks/mesh_build.py [--quick] [--repeat N] [--multi]``. Writes
``benchmarks/results/mesh_build.json`` with median/min seconds, vertex and P2
node counts and quality figures for: graded and uniform meshes of the paper's
single-particle box (3 x 11 mm, 1 mm disk, 24 and 48 outline segments), a
100-particle group with graded surroundings, and remeshing after a move
(compared with building anew).

``--multi`` instead compares the multi-particle kinds (``field``,
the default for more than one particle; ``graded`` circles per particle;
``group``; ``uniform``) on the collapse's block at t = 0, touching grains on the
floor, one layer on the floor and 100 / 1000 scattered grains: build time
(medians, kinds interleaved), quality, DOFs, edges joining two outlines; writes
``benchmarks/results/mesh_multi.json``.
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


def hexagon(c, r=0.4e-3, ang=0.0):
    th = ang + 2.0 * np.pi * np.arange(6) / 6
    return np.vstack([c[0] + r * np.cos(th), c[1] + r * np.sin(th)])


def multi_cases():
    """The cases of tests/test_meshing_field.py (cores 0.8 of 0.5 mm hexagons)."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    import test_meshing_field as cases_mod

    big = (0.0, 0.0, 64e-3, 64e-3)
    return {"collapse block t=0 (5 x 5)": (cases_mod.BOX, cases_mod.block(5)),
            "10 x 10 block": cases_mod.CLEAR["10 x 10 block"][:2],
            "honeycomb 5 x 5 on the floor": cases_mod.TOUCHING["honeycomb 5 x 5 on the floor"][:2],
            "25 in one layer (30 mm box)": (cases_mod.SPREAD_BOX, cases_mod.SPREAD),
            "5 x 5 block (30 mm box)": (cases_mod.SPREAD_BOX, [P + np.array([[5e-3], [0.0]])
                                                      for P in cases_mod.block(5)]),
            "100 scattered (20 x 20 mm)": cases_mod.CLEAR["100 scattered"][:2],
            "1000 scattered (64 x 64 mm)": (big, cases_mod.scattered(1000, big)),
            }, cases_mod.joining_edges


def multi(rep, output):
    cases, joins = multi_cases()
    kinds = ("field", "graded", "group", "uniform")
    rows = []
    for name, (box, parts) in cases.items():
        ks = ("field",) if name.startswith("1000") else kinds
        fns = {k: (lambda k=k, box=box, parts=parts: meshing.build(k, box, parts, delta_l=0.2e-3))
               for k in ks}
        times = {k: [] for k in ks}
        values = {}
        for k in ks:                                       # warm-up, and the mesh
            try:
                values[k] = fns[k]()
            except ValueError as exc:
                values[k] = exc
        for _ in range(min(rep, 3) if name.startswith("1000") else rep):
            for k in ks:                                   # interleaved: same load
                if isinstance(values[k], Exception):
                    continue
                t0 = time.perf_counter()
                fns[k]()
                times[k].append(time.perf_counter() - t0)
        for k in ks:
            v = values[k]
            if isinstance(v, Exception):
                rows.append({"case": name, "kind": k, "error": str(v)})
                continue
            st = meshing.mesh_stats(v)
            row = {"case": name, "kind": k, "median_s": float(np.median(times[k])),
                   "times_s": [float(x) for x in times[k]],
                   "n_vertices": st.n_vertices, "dofs": 2 * st.n_p2_nodes + st.n_vertices,
                   "min_angle_deg": st.min_angle, "max_aspect": st.max_aspect,
                   "joining_edges": int(joins(v).size), "loadavg": list(os.getloadavg())}
            rows.append(row)
            print(f"{name:30s} {k:8s} {1e3 * row['median_s']:8.1f} ms DOFs {row['dofs']:7d} "
                  f"min angle {st.min_angle:5.1f} max R/2r {st.max_aspect:4.2f} "
                  f"joins {row['joining_edges']}")
    out = {"benchmark": "mesh_multi", "machine": platform.platform(), "cpus": os.cpu_count(),
           "delta_l": 0.2e-3, "targets": {"100 grains": "<= 0.5 s", "1000 grains": "<= 5 s"},
           "note": "medians of interleaved builds after one warm-up; DOFs = 2 P2 nodes + "
                   "vertices (P2/P1); joining_edges: mesh edges between two outlines or an "
                   "outline and the wall (0: every gap has two elements across)",
           "results": rows}
    Path(output).parent.mkdir(parents=True, exist_ok=True)
    Path(output).write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {output}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--quick", action="store_true", help="smoke mode: one run each, no file")
    ap.add_argument("--multi", action="store_true",
                    help="multi-particle kinds compared: mesh_multi.json")
    ap.add_argument("--output",
                    default=str(Path(__file__).parent / "results" / "mesh_build.json"))
    args = ap.parse_args(argv)
    if args.multi:
        out = args.output
        if out.endswith("mesh_build.json"):
            out = str(Path(out).with_name("mesh_multi.json"))
        multi(1 if args.quick else min(args.repeat, 5), out)
        return
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
    # remeshing after a move versus building anew with the moved outlines (moving
    # and remeshing need the mesh with its recipe)
    g24, grp = meshing.build("graded", BOX, [d24]), meshing.build("group", GROUP_BOX, group())
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
