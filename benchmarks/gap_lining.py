"""What the lining of narrow gaps buys and costs: pore flux, grain forces, DOFs, run time.

Field meshes line every gap narrower than two outline edges with outline nodes a
fraction ``gap_spacing`` of its width apart (default 1/3, :mod:`meshing.gaps`). As
grains settle every gap between them is narrow, so the lining sets the mesh size of
granular flow. Two measurements per spacing:

``accuracy``
    The touching 3 x 3 honeycomb of :mod:`mesh_accuracy` (steady Stokes, inflow on
    the left, ``delta_l`` = 0.2 mm): DOFs, smallest angle, the pore flux against the
    converged reference stored in ``results/mesh_accuracy.json`` (field mesh at
    ``delta_l`` = 6.25 um), and the drag on every core against the same reference mesh
    (rebuilt and solved once here: ``--no-force-reference`` skips it).
``collapse``
    The bundled ``collapse`` (25 hexagons) with the grid seeded 1, 2, 3 (random initial
    orientations), to ``--t-end``: CPU and wall time, DOFs (mean, largest), steps,
    remeshes, factorisations, the grains' mean height and horizontal spread at the
    marks, each as mean and spread over the seeds (:func:`skfem_granular.collapse.realisations`).

Usage::

    python benchmarks/gap_lining.py accuracy                 # -> results/gap_lining_accuracy.json
    python benchmarks/gap_lining.py collapse --t-end 0.16    # -> results/gap_lining_collapse.json
    python benchmarks/gap_lining.py collapse --spacing 0.3333 1.0 --seeds 1 --t-end 0.02
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks/results"
SPACINGS = (0.3, 1.0 / 3.0, 0.45, 1.0 / np.sqrt(3.0), 0.75, 1.0, 1.5)
COLLAPSE_SPACINGS = (1.0 / 3.0, 1.0 / np.sqrt(3.0), 1.0)
MARKS = (0.05, 0.1, 0.16)


def core_drags(value, cores) -> tuple[list, np.ndarray]:
    """Pore fluxes and the ``(2, K)`` fluid forces on the cores of the honeycomb case."""
    from mesh_accuracy import BOX, U_MAX

    from skfem_granular.fluid import Fluid, solve_steady

    H = BOX[3] - BOX[1]
    vel = {"left": lambda x, y: (U_MAX * 4.0 * y * (H - y) / H ** 2, 0.0 * y),
           "top": (0.0, 0.0), "bottom": (0.0, 0.0),
           **{f"particle{k}": (0.0, 0.0) for k in range(len(cores))}}
    flow = solve_steady(value.mesh, Fluid(density=1000.0, viscosity=1e-3), vel)
    F = np.column_stack([flow.force(f"particle{k}") for k in range(len(cores))])
    return flow, F


def accuracy(spacings, force_reference: bool) -> dict:
    """Pore flux and core forces of the honeycomb for each spacing."""
    from mesh_accuracy import BOX, honeycomb, line_fluxes

    import meshing

    stored = json.loads((RESULTS / "mesh_accuracy.json").read_text())
    ref_flux = stored["results"][stored["reference"]]["pore_flux"]
    cores = honeycomb()
    F_ref = None
    if force_reference:
        t0 = time.process_time()
        value = meshing.build("field", BOX, cores, delta_l=6.25e-6)
        F_ref = core_drags(value, cores)[1]
        print(f"force reference: {time.process_time() - t0:.0f} s CPU", flush=True)
    rows = []
    for g in spacings:
        opts = {"delta_l": 0.2e-3, "gap_spacing": float(g)}
        value = meshing.build("field", BOX, cores, **opts)
        s = meshing.mesh_stats(value)
        q, _ = line_fluxes(value, cores)
        row = {"gap_spacing": float(g), "dofs": 2 * s.n_p2_nodes + s.n_vertices,
               "min_angle_deg": s.min_angle, "pore_flux_error": sum(q[:-1]) / ref_flux - 1.0}
        if F_ref is not None:
            F = core_drags(value, cores)[1]
            scale = np.abs(F_ref[0]).max()
            row["drag_error_max"] = float(np.abs(F[0] - F_ref[0]).max() / scale)
            row["force_error_max"] = float(np.hypot(*(F - F_ref)).max() / np.hypot(*F_ref).max())
        rows.append(row)
        print(json.dumps(row), flush=True)
    return {"benchmark": "gap_lining_accuracy", "reference_pore_flux": ref_flux,
            "reference": "field mesh, delta_l = 6.25 um (results/mesh_accuracy.json)",
            "force_reference": F_ref.tolist() if F_ref is not None else None, "rows": rows}


def collapse_child(spacing: float, seed: int, t_end: float) -> dict:
    """One collapse in this process."""
    from skfem_granular.simulation import Simulation

    sc = seeded_collapse(seed)
    sc = replace(sc, time=replace(sc.time, t_end=t_end),
                 mesh=replace(sc.mesh, gap_spacing=float(spacing)))
    sim = Simulation(sc, output_dir=ROOT / "out" / f"gap_lining_{spacing:.3f}_{seed}",
                     overwrite=True)
    st = sim.stepper
    marks, dofs = {}, []
    wall0, cpu0 = time.perf_counter(), time.process_time()
    for t, _ in sim.evolve(progress=False):
        dofs.append(int(st.space.N))
        for m in MARKS:
            if f"{m:g}" not in marks and t >= m - 1e-9:
                q = sim.dem.positions
                marks[f"{m:g}"] = {"mean_y": float(q[1].mean()), "spread_x": float(q[0].std())}
    return {"gap_spacing": spacing, "seed": seed, "t_end": t_end,
            "wall_s": time.perf_counter() - wall0, "cpu_s": time.process_time() - cpu0,
            "steps": len(dofs), "dofs_mean": float(np.mean(dofs)), "dofs_max": int(max(dofs)),
            "remeshes": int(st.remeshes), **{k: int(v) for k, v in st.factor_counts.items()},
            "marks": marks}


def seeded_collapse(seed: int):
    """The bundled collapse with its grid seeded ``seed`` (random initial orientations)."""
    import tomllib

    from skfem_granular.scene import Scene, bundled

    data = tomllib.loads(Path(bundled("collapse")).read_text())
    data["grid"]["seed"] = seed
    return Scene.from_dict(data, name="collapse")


def run_child(*args) -> dict:
    """This script's ``--child`` run of ``args`` in a fresh interpreter."""
    from child_process import run_child as run

    return run(__file__, *args)


def summarise(runs: list) -> list:
    """Per spacing: mean and spread over seeds of the costs and the marks."""
    from skfem_granular.collapse import realisations

    out = []
    for g in sorted({r["gap_spacing"] for r in runs}):
        rs = [r for r in runs if r["gap_spacing"] == g]
        row = {"gap_spacing": g, "seeds": [r["seed"] for r in rs]}
        for key in ("cpu_s", "wall_s", "dofs_mean", "dofs_max", "steps", "remeshes",
                    "factorizations", "jacobian_refreshes"):
            row[key] = realisations([r[key] for r in rs])
        for m in rs[0]["marks"]:
            for q in ("mean_y", "spread_x"):
                row[f"{q}@{m}"] = realisations([r["marks"][m][q] for r in rs if m in r["marks"]])
        out.append(row)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", nargs="?", choices=("accuracy", "collapse"))
    ap.add_argument("--spacing", type=float, nargs="+", default=None)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--t-end", type=float, default=0.16)
    ap.add_argument("--no-force-reference", action="store_true")
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        print(json.dumps(collapse_child(float(a.child[0]), int(a.child[1]), float(a.child[2]))))
        return
    load0 = list(os.getloadavg())
    if a.what == "accuracy":
        data = accuracy(a.spacing or SPACINGS, not a.no_force_reference)
    else:
        runs = []
        out = a.out or RESULTS / "gap_lining_collapse.json"
        # interleaved: every spacing once per seed, so the machine's load hits all alike
        for seed in a.seeds:
            for g in a.spacing or COLLAPSE_SPACINGS:
                runs.append(run_child(g, seed, a.t_end))
                print(json.dumps({k: v for k, v in runs[-1].items() if k != "marks"}),
                      flush=True)
                data = {"benchmark": "gap_lining_collapse", "runs": runs,
                        "summary": summarise(runs)}
                out.parent.mkdir(parents=True, exist_ok=True)
                out.write_text(json.dumps(data, indent=1) + "\n")
    data.update(cpus=os.cpu_count(), loadavg_start=load0, loadavg_end=list(os.getloadavg()))
    out = a.out or RESULTS / f"gap_lining_{a.what}.json"
    out.write_text(json.dumps(data, indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    main()
