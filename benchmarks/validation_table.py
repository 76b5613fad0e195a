"""Recompute the README's validation table (docs/validation.md cases 1-8).

Usage: ``python benchmarks/validation_table.py [--out DIR]``.

Every case reuses the setup of the test that checks it: meshes from
``tests/helpers.py``, reference formulas and helpers from the test modules
(``tests/`` is put on ``sys.path``). Nothing is asserted here; the numbers
are measured and written to ``DIR/validation.json`` (all values, per case the
mesh size and wall time) and ``DIR/validation.md`` (a markdown table for the
README). ``DIR`` defaults to ``benchmarks/results``.

Orders are ``log2(e_k / e_{k+1})`` between consecutive refinements (the inner
segment count doubles, or h halves, or the time step halves).

BLAS is limited to one thread (as in ``Simulation.run``) so wall times are
comparable between runs on this 2-core machine.
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import test_coupling as tc  # noqa: E402
import test_fluid_navier_stokes as tns  # noqa: E402
import test_fluid_stokes as tst  # noqa: E402
import test_fluid_time as tft  # noqa: E402
import test_simulation as tsim  # noqa: E402
from helpers import annulus, box, regular_polygon  # noqa: E402

import skfem_granular as sg  # noqa: E402
from skfem_granular.coupled import PartitionedCoupling, Staggering  # noqa: E402
from skfem_granular.fluid import ConvergenceError  # noqa: E402
from skfem_granular.scene import Scene  # noqa: E402
from skfem_granular.simulation import Simulation  # noqa: E402


def order(errors):
    e = np.asarray(errors, dtype=float)
    return (np.log2(e[:-1] / e[1:])).tolist()


def mesh_info(space):
    m = space.mesh
    return {"vertices": int(m.p.shape[1]), "triangles": int(m.t.shape[1]), "dofs": int(space.N)}


def timed(fn):
    t0 = time.perf_counter()
    out = fn()
    out["wall_time_s"] = round(time.perf_counter() - t0, 3)
    return out


# --------------------------------------------------------------- cases 1, 2
def area_radius(n, r):
    """Radius of the circle with the area of the regular n-gon of circumradius r."""
    return r * np.sqrt(n * np.sin(2 * np.pi / n) / (2 * np.pi))


def annulus_cases():
    """Translation and rotation on annulus(1, 2, n, 2n, 25/n^2), n = 32, 64, 128."""
    A, B, MU = tst.A, tst.B, tst.MU
    F = tst.drag_concentric(A, B, MU, 1.0)
    T = tst.torque_couette(A, B, MU, 1.0)
    c1 = {"reference": F, "n_inner": [], "meshes": [], "err_consistent": [], "err_traction": [],
          "lift_over_drag": [], "err_consistent_vs_polygon_area_radii": []}
    c2 = {"reference": T, "n_inner": [], "meshes": [], "err_consistent": [], "err_traction": []}
    t1 = t2 = 0.0
    for n in (32, 64, 128):
        t0 = time.perf_counter()
        mesh = annulus(A, B, n, 2 * n, 25.0 / n**2)
        space = sg.TaylorHood(mesh)
        fluid = sg.Fluid(1.0, MU)
        ts_ = time.perf_counter()
        move = sg.solve_steady(space, fluid, {"inner": (1.0, 0.0), "outer": (0.0, 0.0)})
        fc = move.force("inner")
        ft = move.force("inner", method="traction")
        tm = time.perf_counter()
        spin = sg.solve_steady(space, fluid, {"inner": sg.RigidMotion(omega=1.0),
                                              "outer": (0.0, 0.0)})
        tq_c = spin.torque("inner", center=(0, 0))
        tq_t = spin.torque("inner", center=(0, 0), method="traction")
        te = time.perf_counter()
        setup = ts_ - t0
        t1 += setup + (tm - ts_)  # mesh/space build counted in case 1
        t2 += te - tm
        for c in (c1, c2):
            c["n_inner"].append(n)
            c["meshes"].append(mesh_info(space))
        c1["err_consistent"].append(abs(fc[0] / F - 1))
        c1["err_traction"].append(abs(ft[0] / F - 1))
        c1["lift_over_drag"].append(abs(fc[1] / F))
        # diagnostic: the same formula with the radii of circles of the polygons' areas
        # (separates the polygon-vs-circle geometry error from the FEM error)
        F_poly = tst.drag_concentric(area_radius(n, A), area_radius(2 * n, B), MU, 1.0)
        c1["err_consistent_vs_polygon_area_radii"].append(abs(fc[0] / F_poly - 1))
        c2["err_consistent"].append(abs(tq_c / T - 1))
        c2["err_traction"].append(abs(tq_t / T - 1))
    c1["order_consistent_vs_polygon_area_radii"] = order(c1["err_consistent_vs_polygon_area_radii"])
    for c in (c1, c2):
        c["order_consistent"] = order(c["err_consistent"])
        c["order_traction"] = order(c["err_traction"])
    c1["wall_time_s"] = round(t1, 3)
    c2["wall_time_s"] = round(t2, 3)
    c2["note"] = "same meshes as case 1; wall time is the rotation solve alone"
    return c1, c2


# --------------------------------------------------------------- case 3
def faxen_case():
    rows = []
    for k in (0.2, 1 / 3):
        hole = regular_polygon(160, k)
        mesh = box(-6.0, -1.0, 6.0, 1.0, 0.02, hole=hole)
        space = sg.TaylorHood(mesh)
        flow = sg.solve_steady(space, sg.Fluid(1.0, 1.0),
                               {"wall": (0, 0), "particle0": (1.0, 0.0)})
        ref = tst.faxen(k)
        Fc = -flow.force("particle0")[0]
        Ft = -flow.force("particle0", method="traction")[0]
        rows.append({"k": k, "reference_F_over_muU": ref, "F_consistent": Fc, "F_traction": Ft,
                     "err_consistent": abs(Fc / ref - 1), "err_traction": abs(Ft / ref - 1),
                     "mesh": mesh_info(space)})
    return {"rows": rows}


# --------------------------------------------------------------- case 4
def poiseuille_case():
    H, L, mu, G = 1.0, 3.0, 0.01, 2.0
    mesh = box(0.0, 0.0, L, H, 0.02)

    def profile(x, y):
        return G / (2 * mu) * y * (H - y), 0.0 * y

    flow = sg.solve_steady(mesh, sg.Fluid(1.0, mu), {"left": profile, "bottom": (0, 0),
                                                     "top": (0, 0)})
    loc = flow.space.velocity_doflocs
    ux, uy = profile(loc[0], loc[1])
    exact = np.where(flow.space.component == 0, ux, uy)
    umax = G * H**2 / (8 * mu)
    pts = np.array([[0.5, 1.5, 2.5], [0.5, 0.5, 0.5]])
    p = flow.pressure(pts)
    pe = G * (L - pts[0])
    return {"u_max": umax, "max_velocity_err_over_umax": float(np.abs(flow.u - exact).max() / umax),
            "max_pressure_rel_err_at_3_points": float(np.abs(p / pe - 1).max()),
            "mesh": mesh_info(flow.space)}


# --------------------------------------------------------------- case 5
def kovasznay_case():
    eu, ep, its, meshes, res = [], [], [], [], []
    for n in (2, 4, 8):
        flow = sg.solve_steady(tns._mesh(n), sg.Fluid(1.0, 1 / tns.RE), {"all": tns.kovasznay},
                               convection=True)
        a, b = tns._errors(flow)
        eu.append(float(a))
        ep.append(float(b))
        its.append(int(flow.report.iterations))
        res.append(float(flow.report.residuals[-1]))
        meshes.append(mesh_info(flow.space))
    return {"Re": tns.RE, "n": [2, 4, 8], "meshes": meshes, "err_u_L2": eu, "err_p_L2": ep,
            "order_u_L2": order(eu), "order_p_L2": order(ep), "newton_iterations": its,
            "final_residual": res}


# --------------------------------------------------------------- case 6
def taylor_green_case():
    space = sg.TaylorHood(box(0.0, 0.0, np.pi, np.pi, 0.05))
    runs = {}
    specs = {
        "bdf2_constant_NS": ([1.0] * 4, "bdf2", (2, 4, 8, 16), True),
        "bdf2_variable_w2_half_stokes": ([1.0, 2.0, 1.0, 2.0], "bdf2", (4, 8, 16, 32, 64), False),
        "euler_constant_NS": ([1.0] * 4, "euler", (2, 4, 8, 16), True),
    }
    for name, (pattern, scheme, levels, conv) in specs.items():
        t0 = time.perf_counter()
        o, d = tft._orders(space, pattern, scheme, levels, convection=conv)
        runs[name] = {"pattern": pattern, "levels": list(levels), "convection": conv,
                      "steps": [len(pattern) * k for k in levels], "differences": d.tolist(),
                      "orders": o.tolist(), "wall_time_s": round(time.perf_counter() - t0, 3)}
    return {"nu": tft.NU, "T": 1.0, "runs": runs, "mesh": mesh_info(space)}


# --------------------------------------------------------------- case 7
def added_mass_case():
    mesh = annulus(tc.A_IN, tc.B_OUT, tc.N_SEG, 2 * tc.N_SEG, (tc.A_IN * 0.04) ** 2)
    mesh = mesh.with_boundaries({"particle0": mesh.boundaries["inner"],
                                 "wall": mesh.boundaries["outer"]})
    area = 0.5 * tc.N_SEG * tc.A_IN**2 * np.sin(2 * np.pi / tc.N_SEG)
    space = sg.TaylorHood(mesh)
    rows = []
    for ratio in (2.65, 1.1, 0.5, 0.1):
        rho_p = 1000.0 * ratio
        exact = -tc.added_mass_acceleration(rho_p, 1000.0, tc.A_IN, tc.B_OUT, tc.G)
        row = {"ratio": ratio, "exact_acc": exact, "monolithic": {}}
        for dt in (1e-4, 1e-5, 1e-6):
            acc, _ = tc._release(space, area, rho_p, dt=dt)
            row["monolithic"][f"{dt:g}"] = {"acc": acc, "rel_err": abs(acc / exact - 1)}
        # partitioned, as in the test: Stokes (convection=False), 40 sub-iterations, no relaxation
        mono, _ = tc._release(space, area, rho_p, dt=1e-5, convection=False)
        try:
            part, _ = tc._release(space, area, rho_p, cls=PartitionedCoupling, dt=1e-5,
                                  staggering=Staggering(subiterations=40, relaxation=1.0),
                                  convection=False)
            row["partitioned"] = {"status": "converged", "acc": part,
                                  "rel_diff_vs_monolithic_stokes": abs(part / mono - 1),
                                  "rel_err": abs(part / exact - 1)}
        except ConvergenceError as e:
            row["partitioned"] = {"status": "ConvergenceError", "message": str(e)}
        rows.append(row)
    a, b = tc.A_IN, tc.B_OUT
    return {"a": a, "b": b, "C_a": (b**2 + a**2) / (b**2 - a**2),
            "rows": rows, "mesh": mesh_info(space),
            "partitioned_settings": {"dt": 1e-5, "subiterations": 40, "relaxation": 1.0,
                                     "convection": False}}


# --------------------------------------------------------------- case 8
def symmetry_case():
    paper = Scene.bundled("single_particle")
    out = {"t_end": 1e-4, "dt": paper.time.dt}
    for name, scene in (("graded", tsim._short(paper)),
                        ("uniform", tsim._short(paper).with_mesh("uniform"))):
        t0 = time.perf_counter()
        res = Simulation(scene).run(progress=False)
        wall = time.perf_counter() - t0
        h = res.history
        m = res.summary["mesh"]
        vx, vy = float(np.abs(h.vx).max()), float(np.abs(h.vy).max())
        out[name] = {"max_abs_vx": vx, "max_abs_vy": vy, "vx_over_vy": vx / vy,
                     "max_x_drift": float(np.abs(h.x[:, 0] - 1.5e-3).max()),
                     "steps": len(h),
                     "mesh": {"vertices": m["vertices"], "triangles": m["triangles"],
                              "dofs": m["dofs"], "p2_nodes": m["p2_nodes"]},
                     "wall_time_s": round(wall, 3)}
    return out


# --------------------------------------------------------------- table
def fmt(x, d=1):
    return f"{x:.{d}e}"


def fmt_list(xs, d=1):
    return ", ".join(fmt(x, d) for x in xs)


def fmt_orders(xs):
    return ", ".join(f"{x:.2f}" for x in xs)


def mesh_str(m):
    return f"{m['vertices']} v / {m['triangles']} tri / {m['dofs']} DOFs"


def conv(c, key):
    """'e1, e2, e3 (orders o1, o2)' for ``c['err_<key>']`` and ``c['order_<key>']``."""
    return f"{fmt_list(c['err_' + key])} (orders {fmt_orders(c['order_' + key])})"


def markdown(R):
    rows = []
    c = R["case1"]
    ms = "; ".join(f"{n}-gon: {mesh_str(m)}"
                   for n, m in zip(c["n_inner"], c["meshes"], strict=True))
    rows.append(("Concentric cylinders, drag (case 1)", f"annulus, inner 32/64/128-gon ({ms})",
                 f"consistent: {conv(c, 'consistent')}; traction: {conv(c, 'traction')}",
                 c["wall_time_s"]))
    c = R["case2"]
    rows.append(("Couette torque (case 2)", "same three meshes",
                 f"consistent: {conv(c, 'consistent')}; traction: {conv(c, 'traction')}",
                 c["wall_time_s"]))
    c = R["case3"]
    ms = "; ".join(f"k = {r['k']:.3g}: {mesh_str(r['mesh'])}" for r in c["rows"])
    meas = "; ".join(f"k = {r['k']:.3g}: consistent {fmt(r['err_consistent'])}, traction "
                     f"{fmt(r['err_traction'])}" for r in c["rows"])
    rows.append(("Faxen, closed channel (case 3)", f"160-gon in channel 12 x 2 ({ms})",
                 f"relative error of F/(mu U): {meas}", c["wall_time_s"]))
    c = R["case4"]
    rows.append(("Plane Poiseuille (case 4)", f"unstructured 3 x 1 box ({mesh_str(c['mesh'])})",
                 f"max velocity error / u_max = {fmt(c['max_velocity_err_over_umax'])}; "
                 f"pressure at 3 points rel. error {fmt(c['max_pressure_rel_err_at_3_points'])}",
                 c["wall_time_s"]))
    c = R["case5"]
    ms = "; ".join(f"n = {n}: {mesh_str(m)}" for n, m in zip(c["n"], c["meshes"], strict=True))
    rows.append(("Kovasznay Re = 40 (case 5)", f"structured, n = 2/4/8 ({ms})",
                 f"velocity L2: {conv(c, 'u_L2')}; "
                 f"pressure L2: {conv(c, 'p_L2')}; "
                 f"Newton iterations {', '.join(map(str, c['newton_iterations']))}",
                 c["wall_time_s"]))
    c = R["case6"]
    r = c["runs"]
    rows.append(("Taylor-Green, temporal self-convergence (case 6)",
                 f"[0, pi]^2 ({mesh_str(c['mesh'])}), T = 1, nu = 0.1",
                 "BDF2 constant steps (NS, 8/16/32/64 steps): orders "
                 f"{fmt_orders(r['bdf2_constant_NS']['orders'])}; "
                 "BDF2 w = 2, 1/2 alternating (Stokes, 24..384 steps): orders "
                 f"{fmt_orders(r['bdf2_variable_w2_half_stokes']['orders'])}; "
                 f"backward Euler (NS): orders {fmt_orders(r['euler_constant_NS']['orders'])}",
                 c["wall_time_s"]))
    c = R["case7"]
    parts = []
    for row in c["rows"]:
        mono = row["monolithic"]
        errs = "/".join(fmt(mono[k]["rel_err"]) for k in ("0.0001", "1e-05", "1e-06"))
        p = row["partitioned"]
        ptxt = ("partitioned converges" if p["status"] == "converged"
                else "partitioned: ConvergenceError")
        parts.append(f"{row['ratio']:g}: {errs} ({ptxt})")
    rows.append(("Added mass at release (case 7)",
                 f"annulus 64-gon, a = 1 mm, b = 2 mm ({mesh_str(c['mesh'])})",
                 "monolithic relative error of the initial acceleration at dt = 1e-4/1e-5/1e-6 s, "
                 "by rho_p/rho_f: " + "; ".join(parts) +
                 " (partitioned: dt = 1e-5 s, 40 sub-iterations, relaxation 1, Stokes)",
                 c["wall_time_s"]))
    c = R["case8"]
    g, u = c["graded"], c["uniform"]
    rows.append(("Symmetry (case 8)",
                 "single_particle.toml, 0.1 ms: graded, mirror-symmetric "
                 f"({mesh_str(g['mesh'])}); uniform ({mesh_str(u['mesh'])})",
                 f"max abs(vx) / max abs(vy): graded {fmt(g['vx_over_vy'])} (rounding alone); "
                 f"uniform {fmt(u['vx_over_vy'])} (rounding + discretisation)",
                 c["wall_time_s"]))
    lines = ["| reference (docs/validation.md) | mesh (vertices / triangles / DOFs) | measured "
             "| wall time |",
             "|---|---|---|---|"]
    for ref, mesh, meas, wall in rows:
        lines.append(f"| {ref} | {mesh} | {meas} | {wall:.1f} s |")
    meta = R["meta"]
    dirty = " (library with uncommitted changes)" if meta["library_dirty"] else ""
    head = (f"Measured by `benchmarks/validation_table.py` at commit {meta['commit'][:7]}{dirty}, "
            f"{meta['date']}, total {meta['total_wall_time_s']:.0f} s.\n\n")
    c = R["case1"]
    foot = ("\nCase 1 errors are against the circle formula. The inner and outer polygons have "
            "less area than their circles; against the same formula with area-equivalent radii "
            "the consistent-force error is "
            f"{fmt_list(c['err_consistent_vs_polygon_area_radii'])} "
            f"(orders {fmt_orders(c['order_consistent_vs_polygon_area_radii'])}), so most of the "
            "case 1 error is the polygonal geometry, not the FEM.\n")
    return head + "\n".join(lines) + "\n" + foot


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results"))
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    def git(*a):
        return subprocess.run(["git", *a], cwd=ROOT, capture_output=True, text=True).stdout.strip()

    t_all = time.perf_counter()
    R = {}
    with threadpool_limits(1):
        t0 = time.perf_counter()
        R["case1"], R["case2"] = annulus_cases()
        print(f"cases 1-2: {time.perf_counter() - t0:.1f} s", flush=True)
        for key, fn in (("case3", faxen_case), ("case4", poiseuille_case),
                        ("case5", kovasznay_case), ("case6", taylor_green_case),
                        ("case7", added_mass_case)):
            R[key] = timed(fn)
            print(f"{key}: {R[key]['wall_time_s']:.1f} s", flush=True)
        R["case8"] = timed(symmetry_case)
        print(f"case8: {R['case8']['wall_time_s']:.1f} s", flush=True)
    R["meta"] = {"commit": git("rev-parse", "HEAD"),
                 "library_dirty": bool(git("status", "--porcelain", "--",
                                           "skfem_granular", "meshing")),
                 "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
                 "python": platform.python_version(), "machine": platform.machine(),
                 "blas_threads": 1,
                 "total_wall_time_s": round(time.perf_counter() - t_all, 3)}
    (out / "validation.json").write_text(json.dumps(R, indent=2) + "\n")
    md = markdown(R)
    (out / "validation.md").write_text(md)
    print(md)


if __name__ == "__main__":
    main()
