"""Benchmark: cost of the fluid core's building blocks and of 100 BDF2 steps.

Usage: ``python benchmarks/fluid_step.py [--quick] [--cases 1k,9k,40k] [--out PATH]``.

The paper's box (3 x 11 mm, closed), a 1 mm disk moving at 1 cm/s through
water, Taylor-Hood P2/P1, on three meshes of about 1k, 9k and 40k vertices
(recipes below). For each mesh it times, median of several runs:

- Jacobian assembly: the convection Jacobian alone
  (``space.convection.jacobian(u)``) and the full reduced BDF2 Newton matrix
  (``op.reduced_jacobian(x, c_mass=a0)``; the older path ``op.jacobian`` +
  ``op.reduced`` is timed too);
- the fill-reducing ordering (once per mesh) and the factorisation with it,
  against SuperLU's own ``MMD_AT_PLUS_A`` on the same matrix;
- factorisation of that matrix (SuperLU; PARDISO only when ``pypardiso`` is
  installed) and one solve (with iterative refinement; the raw triangular
  solve is reported too);
- force on the particle, consistent (residual) and traction methods;
- one fresh Newton iteration (fresh factorisation; the ordering and the index maps of
  a pattern seen before reused, the first two on a mesh reported apart):
  residual + assembly + factorisation + solve (the
  solve as in ``solve_steady``'s Newton loop: one triangular solve whose
  residual is checked, no refinement);
- 100 BDF2 steps at dt = 1e-5 s on the fixed mesh with ``sg.evolve``,
  with and without convection (fewer steps on the 40k mesh, extrapolated and
  flagged as such, to keep the whole run near ten minutes: there 100 steps
  are estimated as the first two steps, which factorise, plus 98 times the
  mean of the later ones).

Writes ``benchmarks/results/fluid_step.json`` and prints a markdown table.
The machine may be shared: the load average before and after is recorded.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from pathlib import Path

import numpy as np

import meshing
import skfem_granular as sg
from skfem_granular.fluid.boundary import DirichletData
from skfem_granular.fluid.flow import Flow
from skfem_granular.fluid.linsolve import SuperLUSolver
from skfem_granular.fluid.operator import NavierStokesOperator

DOMAIN = (0.0, 0.0, 3e-3, 11e-3)
RADIUS, CENTER = 0.5e-3, (1.5e-3, 5.5e-3)
FLUID = sg.Fluid(1000.0, 1e-3)
VELOCITY = {"wall": (0.0, 0.0), "particle0": (0.0, -0.01)}
DT = 1e-5
A0 = 1.5 / DT  # BDF2 with constant steps

#: Targets set for the fluid core (2-core machine), seconds.
TARGETS = {
    "1k": {"steps_100": 1.5, "newton_iteration": 0.06},
    "9k": {"steps_100": 20.0, "newton_iteration": 1.2, "jacobian_assembly": 0.1},
}


def disk(n: int) -> np.ndarray:
    """Counter-clockwise regular ``n``-gon of the paper's 1 mm particle."""
    t = 2 * np.pi * np.arange(n) / n
    return np.array([CENTER[0] + RADIUS * np.cos(t), CENTER[1] + RADIUS * np.sin(t)])


#: name -> (recipe text, builder, repeats of the micro-benchmarks, steps, repeats of the
#: step runs, solver of the step runs). On the 40k mesh (357k DOFs) "auto" would pick the
#: Krylov solver, measured at 16 s setup + 45 s per solve there: SuperLU is used instead.
CASES = {
    "1k": ("graded_mesh(DOMAIN, [regular 60-gon]), default sigma (Eq. 4)",
           lambda: meshing.graded_mesh(DOMAIN, [disk(60)]), 11, 100, 3, "auto"),
    "9k": ("uniform_mesh(DOMAIN, [regular 24-gon], h=delta_l=0.067 mm)",
           lambda: meshing.uniform_mesh(DOMAIN, [disk(24)], h=0.067e-3, delta_l=0.067e-3),
           7, 100, 1, "auto"),
    "40k": ("uniform_mesh(DOMAIN, [regular 24-gon], h=delta_l=0.0315 mm)",
            lambda: meshing.uniform_mesh(DOMAIN, [disk(24)], h=0.0315e-3, delta_l=0.0315e-3),
            1, 3, 1, "superlu"),
}


def timed(fn, repeats: int) -> tuple[float, list, object]:
    """Median wall time of ``repeats`` calls of ``fn``, all times, last result."""
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), times, out


class CountingLU:
    """Wraps a SuperLU object to count triangular solves (refinement sweeps)."""

    def __init__(self, lu):
        self.lu, self.count = lu, 0

    def solve(self, b):
        self.count += 1
        return self.lu.solve(b)


def run_steps(space, convection: bool, steps: int, solver: str = "auto") -> dict:
    """``steps`` BDF2 steps of ``sg.evolve``; wall time and what the integrator did."""
    its, refreshes, stamps = [], 0, []
    t0 = time.perf_counter()
    flow = None
    for _, flow in sg.evolve(space, FLUID, VELOCITY, dt=DT, t_end=steps * DT,
                             convection=convection, solver=solver):
        stamps.append(time.perf_counter() - t0)
        its.append(flow.step.iterations)
        refreshes += flow.step.refreshes
    el = stamps[-1]
    # the first two steps factorise (backward Euler, then BDF2); the rest reuse it
    n = len(stamps)
    est = el if n >= 100 else stamps[1] + (el - stamps[1]) / (n - 2) * 98
    return {"seconds": el, "seconds_100_steps": est, "steps": n,
            "mean_iterations": float(np.mean(its)), "jacobian_refreshes": refreshes,
            "wall_time": flow.report.wall_time, "solver": flow.report.solver, "flow": flow}


def bench_case(name: str, quick: bool) -> dict:
    recipe, build, reps, steps, step_reps, solver = CASES[name]
    if quick:
        reps, steps, step_reps = max(1, reps // 3), min(steps, 10), 1
    out = {"case": name, "recipe": recipe, "step_solver": solver}
    t0 = time.perf_counter()
    mesh = build()
    out["mesh_build"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    space = sg.TaylorHood(mesh)
    for blk in ("M", "K_symmetric", "B", "Mp", "convection"):
        getattr(space, blk)
    out["space_setup"] = time.perf_counter() - t0
    op = NavierStokesOperator(space, FLUID, DirichletData(space, VELOCITY), convection=True)
    out.update(vertices=int(mesh.nvertices), elements=int(mesh.nelements),
               p2_nodes=int(space.sb.N), velocity_dofs=int(space.nu),
               pressure_dofs=int(space.np_), dofs=int(space.N), free_dofs=int(op.free.size))
    t = {}
    # a state: one fresh Newton step of the BDF2 corrector from rest with the boundary data
    x = op.apply_dirichlet(np.zeros(space.N))
    u = x[: space.nu]
    # first call: builds the cached tables (convection matrix table, velocity block for a0,
    # positions of its entries in the convection pattern); timed separately
    t["first_jacobian_call"], _, _ = timed(lambda: op.reduced_jacobian(x, c_mass=A0), 1)
    t["convection_jacobian"], _, _ = timed(lambda: space.convection.jacobian(u), reps)
    t["jacobian_full"], _, J = timed(lambda: op.jacobian(x, c_mass=A0), reps)
    t["reduce"], _, Jr = timed(lambda: op.reduced(J), reps)
    t["jacobian_assembly_full_then_reduce"], _, _ = timed(
        lambda: op.reduced(op.jacobian(x, c_mass=A0)), reps)
    t["jacobian_assembly"], _, _ = timed(lambda: op.reduced_jacobian(x, c_mass=A0), reps)
    t["ordering"], _, _ = timed(lambda: space.ordering(op.free), 1)
    t["residual"], _, _ = timed(lambda: op.residual(x, c_mass=A0), max(reps, 3))
    # one fresh Newton iteration, timed by phase (its factorisation is the SuperLU timing)
    phases = {"residual": [], "jacobian_assembly": [], "factor_superlu": [], "solve_superlu": [],
              "newton_iteration": []}
    phases_mmd = []
    for _ in range(reps):
        t0 = time.perf_counter()
        rr = op.residual(x, c_mass=A0)
        t1 = time.perf_counter()
        JJ = op.reduced_jacobian(x, c_mass=A0)
        t2 = time.perf_counter()
        slu = SuperLUSolver().factorize(JJ, op.nu_free, **op.solver_blocks(A0))
        t3 = time.perf_counter()
        rhs = -rr[op.free]
        slu.solve_correction(rhs)  # as solve_steady's Newton loop: residual-checked, unrefined
        t4 = time.perf_counter()
        for k, v in zip(phases, (t1 - t0, t2 - t1, t3 - t2, t4 - t3, t4 - t0), strict=True):
            phases[k].append(v)
        # the same factorisation with SuperLU's own ordering, interleaved for a fair ratio
        blocks = dict(op.solver_blocks(A0), ordering=None)
        t0 = time.perf_counter()
        SuperLUSolver().factorize(JJ, op.nu_free, **blocks)
        phases_mmd.append(time.perf_counter() - t0)
    out["newton_iteration_phases"] = phases
    # the first two factorisations of a pattern on a mesh go the general way (the second
    # builds the index maps of factor_plan); later ones reuse them: medians over those,
    # the first two reported on their own
    known = slice(2, None) if reps > 3 else slice(None)
    t.update({k + "_in_newton": statistics.median(v[known]) for k, v in phases.items()
              if k not in ("newton_iteration",)})
    t["newton_iteration"] = statistics.median(phases["newton_iteration"][known])
    out["newton_iteration_first_two_on_mesh"] = phases["newton_iteration"][:2]
    out["factor_superlu_mmd_at_plus_a"] = phases_mmd
    t["factor_superlu_mmd_at_plus_a"] = statistics.median(phases_mmd[known])
    t["factor_superlu"] = t.pop("factor_superlu_in_newton")
    out["superlu_factor_nnz"] = int(slu._lu.L.nnz + slu._lu.U.nnz)
    t["solve_superlu"], _, _ = timed(lambda: slu.solve(rhs), max(reps, 3))
    counter = CountingLU(slu._lu)
    slu._lu = counter
    slu.solve(rhs)
    slu._lu = counter.lu
    out["superlu_triangular_solves_per_solve"] = counter.count
    b = slu._scale * rhs
    t["triangular_solve_superlu"], _, _ = timed(lambda: slu._lu.solve(b), max(reps, 3))
    try:
        from skfem_granular.fluid.linsolve import PardisoSolver

        t["factor_pardiso"], _, pds = timed(
            lambda: PardisoSolver().factorize(JJ, op.nu_free), reps)
        t["solve_pardiso"], _, _ = timed(lambda: pds.solve(rhs), reps)
        out["pardiso"] = "installed"
    except ValueError:
        out["pardiso"] = "not installed (skipped)"
    # unsteady runs
    runs = {}
    for conv in (True, False):
        key = "navier_stokes" if conv else "stokes"
        secs, last = [], None
        for _ in range(step_reps):
            last = run_steps(space, conv, steps, solver)
            secs.append(last["seconds_100_steps"])
        flow = last.pop("flow")
        last.update(seconds_100_steps=statistics.median(secs), all_seconds_100_steps=secs,
                    extrapolated=steps != 100)
        runs[key] = last
        if conv:
            final_flow = flow
    out["steps"] = runs
    t["steps_100_navier_stokes"] = runs["navier_stokes"]["seconds_100_steps"]
    t["steps_100_stokes"] = runs["stokes"]["seconds_100_steps"]
    # forces on the final Navier-Stokes state (fresh flows: the residual is evaluated once each)
    fl = final_flow

    def fresh():
        return Flow(fl.operator, fl.x, fl._residual_fn, t=fl.t)

    t["force_consistent"], _, F_c = timed(lambda: fresh().force("particle0"), max(reps, 5))
    t["force_consistent_cached"], _, _ = timed(lambda: fl.force("particle0"), max(reps, 5))
    t["force_traction"], _, F_t = timed(lambda: fl.force("particle0", method="traction"),
                                        max(reps, 5))
    out["force"] = {"t": fl.t, "consistent": F_c.tolist(), "traction": F_t.tolist()}
    out["times"] = t
    out["ratios"] = {
        "navier_stokes_over_stokes_steps": t["steps_100_navier_stokes"] / t["steps_100_stokes"],
        "solve_over_triangular_solve": t["solve_superlu"] / t["triangular_solve_superlu"],
        "factor_share_of_newton_iteration": t["factor_superlu"] / t["newton_iteration"],
        "assembly_share_of_newton_iteration": t["jacobian_assembly"] / t["newton_iteration"],
        "convection_share_of_assembly": t["convection_jacobian"] / t["jacobian_assembly"],
        "traction_over_consistent_force": t["force_traction"] / t["force_consistent"],
        "newton_iteration_over_chord_step":
            t["newton_iteration"] / (t["steps_100_navier_stokes"] / 100),
    }
    out["ratios"]["superlu_own_ordering_over_mesh_ordering"] = (
        t["factor_superlu_mmd_at_plus_a"] / t["factor_superlu"])
    if "factor_pardiso" in t:
        out["ratios"]["superlu_over_pardiso_factor"] = t["factor_superlu"] / t["factor_pardiso"]
    if name in TARGETS:
        tg = TARGETS[name]
        out["targets"] = tg
        out["ratios"]["vs_target"] = {k: t[k] / v for k, v in tg.items() if k != "steps_100"}
        out["ratios"]["vs_target"]["steps_100_navier_stokes"] = (
            t["steps_100_navier_stokes"] / tg["steps_100"])
        out["ratios"]["vs_target"]["steps_100_stokes"] = t["steps_100_stokes"] / tg["steps_100"]
    return out


def table(results: list) -> str:
    rows = [
        ("vertices", "vertices", "{:d}"), ("P2 nodes", "p2_nodes", "{:d}"),
        ("DOFs (free)", None, None),
        ("convection Jacobian [s]", "convection_jacobian", "{:.4f}"),
        ("Jacobian assembly, full reduced matrix [s]", "jacobian_assembly", "{:.4f}"),
        ("residual [s]", "residual", "{:.4f}"),
        ("fill-reducing ordering, once per mesh [s]", "ordering", "{:.3f}"),
        ("factorisation SuperLU, that ordering [s]", "factor_superlu", "{:.3f}"),
        ("factorisation SuperLU, own MMD_AT_PLUS_A [s]", "factor_superlu_mmd_at_plus_a",
         "{:.3f}"),
        ("factorisation PARDISO [s]", "factor_pardiso", "{:.3f}"),
        ("one solve (refined) [s]", "solve_superlu", "{:.4f}"),
        ("one triangular solve [s]", "triangular_solve_superlu", "{:.4f}"),
        ("force, consistent (incl. residual) [ms]", "force_consistent", "ms"),
        ("force, traction [ms]", "force_traction", "ms"),
        ("fresh Newton iteration [s]", "newton_iteration", "{:.3f}"),
        ("100 BDF2 steps, Navier-Stokes [s]", "steps_100_navier_stokes", "{:.2f}"),
        ("100 BDF2 steps, Stokes [s]", "steps_100_stokes", "{:.2f}"),
    ]
    head = "| quantity | " + " | ".join(r["case"] for r in results) + " |"
    lines = [head, "|---" * (len(results) + 1) + "|"]
    for label, key, fmt in rows:
        cells = []
        for r in results:
            if key is None:
                cells.append(f"{r['dofs']} ({r['free_dofs']})")
            elif key in ("vertices", "p2_nodes"):
                cells.append(fmt.format(r[key]))
            elif key not in r["times"]:
                cells.append("-")
            elif fmt == "ms":
                cells.append(f"{1e3 * r['times'][key]:.2f}")
            else:
                v = fmt.format(r["times"][key])
                if key.startswith("steps_100") and r["steps"]["stokes"]["extrapolated"]:
                    v += f" (from {r['steps']['stokes']['steps']} steps)"
                cells.append(v)
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats and 10 steps (smoke test)")
    ap.add_argument("--cases", default="1k,9k,40k", help="comma-separated subset of 1k,9k,40k")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "fluid_step.json"))
    args = ap.parse_args(argv)
    try:
        from threadpoolctl import threadpool_info

        blas = [(i.get("internal_api"), i.get("num_threads")) for i in threadpool_info()]
    except ImportError:
        blas = "threadpoolctl not installed"
    meta = {"python": platform.python_version(), "machine": platform.machine(),
            "cpus": os.cpu_count(), "numpy": np.__version__,
            "scipy": __import__("scipy").__version__,
            "skfem": __import__("skfem").__version__, "blas_threads": blas,
            "loadavg_start": os.getloadavg(), "dt": DT, "a0": A0,
            "date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    t_start = time.perf_counter()
    results = []
    for name in args.cases.split(","):
        print(f"case {name} ...", flush=True)
        res = bench_case(name.strip(), args.quick)
        print(f"  {res['vertices']} vertices, {res['dofs']} DOFs: "
              f"{json.dumps({k: round(v, 4) for k, v in res['times'].items()})}", flush=True)
        results.append(res)
    meta["loadavg_end"] = os.getloadavg()
    meta["total_seconds"] = time.perf_counter() - t_start
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"meta": meta, "results": results}, indent=1, default=float))
    print()
    print(table(results))
    print(f"\nload average {meta['loadavg_start']} -> {meta['loadavg_end']}; "
          f"total {meta['total_seconds']:.0f} s; written {out}")


if __name__ == "__main__":
    main()
