"""Benchmark: pore flux through a touching honeycomb on several meshes.

Usage: ``python benchmarks/mesh_accuracy.py [--quick] [--only NAME ...] [--core 0.9]``.
Writes ``benchmarks/results/mesh_accuracy.json`` (``mesh_accuracy_core<c>.json`` for
another core ratio than 0.8).

The case: a touching 3 x 3 honeycomb of hexagons (shadow circumradius 0.5 mm, cores
0.8 of it or ``--core`` of it, shadows touching each other and the floor) in the 20 x
10 mm box, a slow parabolic inflow on the left (peak 1 mm/s), no slip on the floor,
the top and the cores, do-nothing outflow on the right; steady Stokes. The pore flux
is the integral of ``u_x`` over the pores on the vertical line through the middle
column's centres: the fluid intervals from the floor to the column's top core (Gauss-
Legendre on each). The strip from that core up to the top of the block's shadows
(0.087 mm, open to the flow over the block, not a pore) is recorded apart. Every
mesh's fluxes are compared with the finest mesh's, whose own convergence is recorded
(against the mesh before it).
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

BOX = (0.0, 0.0, 20e-3, 10e-3)
R = 0.5e-3           # shadow circumradius
CORE = 0.8           # core ratio
X0 = 5e-3            # first column's centre
U_MAX = 1e-3         # peak inflow (m/s)
GAUSS = 40           # Gauss points per fluid interval


def hexagon(c, r=CORE * R):
    """The regular hexagon of circumradius ``r`` about ``c``: ``(2, 6)``."""
    th = 2.0 * np.pi * np.arange(6) / 6
    return np.vstack([c[0] + r * np.cos(th), c[1] + r * np.sin(th)])


def honeycomb(nx=3, ny=3, x0=X0, core=CORE):
    """Cores (``core`` of the shadow) of hexagons whose shadows tile the floor and each
    other (all touching)."""
    a = R * np.sqrt(3.0) / 2.0
    return [hexagon((x0 + i * 1.5 * R, a + 2 * a * j + (a if i % 2 else 0.0)), core * R)
            for i in range(nx) for j in range(ny)]


def fluid_intervals(x, top, cores):
    """The parts of the segment ``(x, 0) -> (x, top)`` outside every core."""
    cuts = []
    for P in cores:
        if P[0].min() < x < P[0].max():
            # crossing of the vertical line with the convex polygon's edges
            Q = np.roll(P, -1, axis=1)
            s = (x - P[0]) / np.where(Q[0] != P[0], Q[0] - P[0], np.inf)
            ok = (s >= 0.0) & (s <= 1.0)
            y = P[1, ok] + s[ok] * (Q[1, ok] - P[1, ok])
            cuts.append((y.min(), y.max()))
    cuts.sort()
    out, y0 = [], 0.0
    for a, b in cuts:
        if a > y0:
            out.append((y0, min(a, top)))
        y0 = max(y0, b)
    if y0 < top:
        out.append((y0, top))
    return out


def line_fluxes(value, cores):
    """Steady Stokes fluxes (m^2/s per unit depth) through each fluid interval of the
    middle column's line (floor to the top of the block's shadows), and the solve's
    wall time. The last interval, above the column's top core, is open to the flow
    over the block; the others are the pores."""
    from skfem_granular.fluid import Fluid, solve_steady

    H = BOX[3] - BOX[1]
    vel = {"left": lambda x, y: (U_MAX * 4.0 * y * (H - y) / H ** 2, 0.0 * y),
           "top": (0.0, 0.0), "bottom": (0.0, 0.0),
           **{f"particle{k}": (0.0, 0.0) for k in range(len(cores))}}
    t0 = time.perf_counter()
    flow = solve_steady(value.mesh, Fluid(density=1000.0, viscosity=1e-3), vel)
    a = R * np.sqrt(3.0) / 2.0
    x = X0 + 1.5 * R
    top = 2 * a * 3 + a
    g, w = np.polynomial.legendre.leggauss(GAUSS)
    q = []
    for y0, y1 in fluid_intervals(x, top, cores):
        y = 0.5 * (y0 + y1) + 0.5 * (y1 - y0) * g
        u = flow.velocity(np.vstack([np.full_like(y, x), y]))[0]
        q.append(0.5 * (y1 - y0) * float(w @ u))
    return q, time.perf_counter() - t0


#: name -> (kind, options)
MESHES = {
    "field 0.2": ("field", {"delta_l": 0.2e-3}),
    "uniform 0.2": ("uniform", {"delta_l": 0.2e-3, "h": 0.2e-3}),
    "field 0.1": ("field", {"delta_l": 0.1e-3}),
    "uniform 0.1": ("uniform", {"delta_l": 0.1e-3, "h": 0.1e-3}),
    "field 0.05": ("field", {"delta_l": 0.05e-3}),
    "field 0.025": ("field", {"delta_l": 0.025e-3}),
    "field 0.0125": ("field", {"delta_l": 0.0125e-3}),
    "field 0.00625": ("field", {"delta_l": 0.00625e-3}),
}
REFERENCE, CHECK = "field 0.00625", "field 0.0125"
"""The reference (outline edges 1/32 of the default's, no gap narrower than 2 of
them, so no outline edge split) and the mesh its convergence is checked against."""


def run(names, output, core=CORE):
    cores = honeycomb(core=core)
    rows = {}
    for name in names:
        kind, opts = MESHES[name]
        t0 = time.perf_counter()
        value = meshing.build(kind, BOX, cores, **opts)
        t_mesh = time.perf_counter() - t0
        s = meshing.mesh_stats(value)
        q, t_solve = line_fluxes(value, cores)
        rows[name] = {"kind": kind, "options": opts, "dofs": 2 * s.n_p2_nodes + s.n_vertices,
                      "min_angle_deg": s.min_angle, "max_aspect": s.max_aspect,
                      "pore_flux": sum(q[:-1]), "pores": q[:-1], "strip_over_block": q[-1],
                      "mesh_s": t_mesh, "solve_s": t_solve}
        print(f"{name:16s} DOFs {rows[name]['dofs']:7d} pore flux {sum(q[:-1]):.6e} strip "
              f"{q[-1]:.6e} min angle {s.min_angle:5.1f} mesh {t_mesh:.2f} s solve "
              f"{t_solve:.1f} s", flush=True)
    if REFERENCE in rows:
        ref = rows[REFERENCE]
        for name, r in rows.items():
            r["pore_flux_error"] = r["pore_flux"] / ref["pore_flux"] - 1.0
            r["pores_error"] = [a / b - 1.0 for a, b in zip(r["pores"], ref["pores"],
                                                              strict=True)]
            r["strip_error"] = r["strip_over_block"] / ref["strip_over_block"] - 1.0
            print(f"{name:16s} pore flux {100 * r['pore_flux_error']:+7.3f} % (pores "
                  + " ".join(f"{100 * e:+6.2f}" for e in r["pores_error"])
                  + f" %), strip over the block {100 * r['strip_error']:+7.2f} %")
    out = {"benchmark": "mesh_accuracy", "machine": platform.platform(),
           "loadavg": list(os.getloadavg()), "case": " ".join(__doc__.split("\n\n")[1].split()),
           "core_ratio": core, "reference": REFERENCE, "reference_check": CHECK, "results": rows}
    if output:
        Path(output).parent.mkdir(parents=True, exist_ok=True)
        Path(output).write_text(json.dumps(out, indent=2) + "\n")
        print(f"wrote {output}")
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--only", nargs="*", default=None, help="mesh names to run")
    ap.add_argument("--quick", action="store_true", help="the default mesh only, no file")
    ap.add_argument("--core", type=float, default=CORE, help="core over shadow, in (0, 1)")
    ap.add_argument("--output", default=None, help="default: results/mesh_accuracy.json, "
                    "or mesh_accuracy_core<c>.json for another --core")
    args = ap.parse_args(argv)
    if not 0.0 < args.core < 1.0:
        ap.error(f"--core {args.core!r}: must be in (0, 1)")
    output = args.output or str(Path(__file__).parent / "results" / (
        "mesh_accuracy.json" if args.core == CORE else f"mesh_accuracy_core{args.core:g}.json"))
    names = ["field 0.2"] if args.quick else (args.only or list(MESHES))
    run(names, None if args.quick or args.only else output, core=args.core)


if __name__ == "__main__":
    main()
