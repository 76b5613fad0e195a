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

import meshing
from skfem_granular.validation.pore_flux import BOX, CORE, honeycomb, line_fluxes

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
