"""Sedimentation checked against physics and the literature (long versions).

Checks (``--check``), each writing ``benchmarks/results/sedimentation_<check>[_<tag>].json``
and printing a markdown table:

- ``terminal`` (check 1): the terminal velocity by the particle-frame steady
  Navier-Stokes route (:func:`skfem_granular.validation.terminal_velocity_frame_solve`)
  for the paper's disk in its 3 mm channel (k = 1/3, scene ``settling_disk_k3``)
  and the 2.5 mm disk in a 2 cm channel (k = 1/8, scene ``settling_disk_k8_tall``),
  at two mesh resolutions, with the channel-length sensitivity. ``--coupled``
  also runs the free-settling scenes and compares their velocity plateau
  (long: for the moving-mesh runs).
- ``settling`` (check 2): scene ``settling_disk_channel`` (Glowinski et al. 2001,
  Wan & Turek 2006): maximum particle Reynolds number, plateau, trajectory.
- ``dkt`` (check 3): scene ``dkt_two_disks``: drafting, kissing and tumbling times.
- ``migration`` (check 4): scene ``migration_off_centre``: the offset from the
  centreline over time.
- ``shape`` (check 5): scenes ``settling_rectangle`` (long-axis angle to the
  horizontal) and ``settling_hexagon`` (spurious rotation).
- ``cost`` (check 7): the accuracy-vs-cost study of check 2's maximum particle
  Reynolds number and settling time (:mod:`skfem_granular.studies.settling`) over
  outline resolution, grading, time step, remesh threshold and mesh motion; runs
  resume from ``out/study_settling[_smoke]/runs``; table to
  ``benchmarks/results/study_settling.md``, figures to
  ``docs/figures/study_settling_{pareto,convergence}.png`` (not with ``--smoke``).
- ``repose`` (check 6, dry): scene ``repose_hexagons`` and its irregular-polygon
  and 24-gon variants: angle of repose fitted to the free surface.

Options passed through to the scene: ``--t-end``, ``--dt``, ``--delta-l``,
``--sigma``, ``--adaptive/--tol``, ``--remesh-fraction``, ``--remesh-travel`` and
``--mesh-motion``
(``ale`` | ``fixed``: set when the Scene has a ``mesh_motion`` field, otherwise
ignored with a printed note). Literature values come from
``skfem_granular.validation_data.load("sedimentation")`` (docs/sedimentation.md).

Usage::

    python benchmarks/sedimentation.py --check terminal
    python benchmarks/sedimentation.py --check settling --t-end 0.1 --tag short
    python benchmarks/sedimentation.py --check repose --shape hexagons irregular
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

from skfem_granular.scene import Scene, TimeSpec
from skfem_granular.validation import FrameProblem, measures, terminal_velocity_frame_solve
from skfem_granular.validation_data import load

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
CHECKS = ("terminal", "settling", "dkt", "migration", "shape", "repose", "cost")


# ------------------------------------------------------------------ scenes
def configure(scene: Scene, args) -> tuple[Scene, list[str]]:
    """The scene with the command-line overrides; returns it and the notes printed."""
    notes = []
    t = scene.time
    tkw = {}
    if args.t_end is not None:
        tkw["t_end"] = args.t_end
    if args.dt is not None:
        tkw["dt"] = args.dt
    if args.adaptive:
        tkw["adaptive"] = True
        if args.tol is not None:
            tkw["tol"] = args.tol
    if tkw:
        new = dataclasses.asdict(t) | tkw
        new["dt"] = min(new["dt"], new["t_end"])
        scene = dataclasses.replace(scene, time=TimeSpec(**new))
    mkw = {k: v for k, v in (("delta_l", args.delta_l), ("sigma", args.sigma)) if v is not None}
    if mkw:
        scene = dataclasses.replace(scene, mesh=dataclasses.replace(scene.mesh, **mkw))
    if args.remesh_fraction is not None:
        scene = dataclasses.replace(scene, remesh_fraction=args.remesh_fraction)
    if args.remesh_travel is not None:
        scene = dataclasses.replace(scene, remesh_travel=args.remesh_travel)
    if args.mesh_motion is not None:
        names = {f.name for f in dataclasses.fields(scene)}
        if "mesh_motion" in names:
            scene = dataclasses.replace(scene, mesh_motion=args.mesh_motion)
        else:
            notes.append(f"--mesh-motion {args.mesh_motion}: this Scene has no mesh_motion "
                         "field yet (moving mesh not merged); ignored, the run remeshes")
    scene = dataclasses.replace(scene, output_dir=args.out)
    return scene, notes


def run_scene(scene: Scene, on_step=None):
    """Run ``scene`` to its end; returns (history, summary, wall time, failure or None).

    ``on_step(sim, t)``, if given, is called after every accepted step (to look at
    the mesh in use, e.g. its symmetry).
    """
    from skfem_granular.coupled.stepper import SimulationError
    from skfem_granular.simulation import Simulation

    t0 = time.perf_counter()
    sim = Simulation(scene)
    failure = None
    try:
        for t, _ in sim.evolve(progress=False):
            if on_step is not None:
                on_step(sim, t)
    except SimulationError as exc:  # keep what was computed
        failure = str(exc)
    res = sim.result
    return res.history, res.summary, time.perf_counter() - t0, failure


def core_diameter(spec) -> float:
    """Twice the core circumradius of a particle spec (the disk the fluid sees)."""
    V = spec.polygon.vertices
    return 2.0 * float(np.hypot(*(V - spec.polygon.centroid[:, None])).max()) * spec.core_ratio


def shadow_radius(spec) -> float:
    V = spec.polygon.vertices
    return float(np.hypot(*(V - spec.polygon.centroid[:, None])).max())


def run_info(scene, summary, wall, failure, notes):
    return {"scene": scene.name, "t_end": scene.time.t_end, "dt": scene.time.dt,
            "adaptive": scene.time.adaptive, "mesh": summary.get("mesh"),
            "mesh_options": dataclasses.asdict(scene.mesh),
            "remesh_fraction": scene.remesh_fraction, "remeshes": summary.get("remeshes"),
            "steps": summary.get("steps"), "wall_time_s": round(wall, 2),
            "phases_s": summary.get("wall_time"), "failed": failure, "notes": notes}


# ------------------------------------------------------------------ check 1
def check_terminal(args) -> dict:
    cases = {"paper_disk_k3": Scene.bundled("settling_disk_k3"),
             "disk_k8": Scene.bundled("settling_disk_k8_tall")}
    rows = []
    for name, sc in cases.items():
        base = FrameProblem.from_scene(sc)
        # resolution 1: the scene's outline and mesh options; resolution 2: outline edges
        # halved, gentler grading
        edge = 2.0 * base.radius * np.sin(np.pi / base.sides)
        levels = {"scene": {},
                  "fine": {"delta_l": 0.5 * edge, "sigma": 1.1}}
        for level, kw in levels.items():
            r = terminal_velocity_frame_solve(base, **kw)
            rows.append({"case": name, "level": level, "U": r.U, "Re": r.reynolds,
                         "residual": r.residual, "iterations": r.iterations,
                         "converged": r.converged, "lift_over_weight": r.lift / r.weight,
                         "stokes_F_over_muU": r.stokes["F_over_muU"],
                         "faxen": r.stokes["faxen_area_radius"],
                         "stokes_rel_error": r.stokes["rel_error"], "mesh": r.mesh,
                         "problem": r.problem, "wall_time_s": round(r.wall_time, 2)})
            print(f"  {name} {level}: U = {r.U:.6g} m/s, Re = {r.reynolds:.4g} "
                  f"({r.iterations} solves, {r.wall_time:.1f} s)", flush=True)
        # boundary conditions: the channel twice as long on both sides
        r2 = terminal_velocity_frame_solve(base, upstream=2 * base.upstream,
                                           downstream=2 * base.downstream)
        rows.append({"case": name, "level": "scene, channel x2", "U": r2.U, "Re": r2.reynolds,
                     "residual": r2.residual, "iterations": r2.iterations,
                     "converged": r2.converged, "lift_over_weight": r2.lift / r2.weight,
                     "stokes_F_over_muU": r2.stokes["F_over_muU"],
                     "faxen": r2.stokes["faxen_area_radius"],
                     "stokes_rel_error": r2.stokes["rel_error"], "mesh": r2.mesh,
                     "problem": r2.problem, "wall_time_s": round(r2.wall_time, 2)})
    out = {"check": 1, "frame_solve": rows}
    if args.coupled:
        out["coupled"] = []
        for name, sc in cases.items():
            scene, notes = configure(sc, args)
            hist, summary, wall, failure = run_scene(scene)
            pl = measures.velocity_plateau(hist.t, hist.vy[:, 0])
            U = next(r["U"] for r in rows if r["case"] == name and r["level"] == "scene")
            out["coupled"].append({"case": name, "plateau": pl,
                                   "rel_diff_to_frame": abs(pl["plateau"]) / U - 1.0,
                                   **run_info(scene, summary, wall, failure, notes)})
    print("\n| case | mesh | vertices | U (m/s) | Re | solves | Stokes F/(mu U) vs Faxen | wall |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['case']} | {r['level']} | {r['mesh']['vertices']} | {r['U']:.6g} | "
              f"{r['Re']:.4g} | {r['iterations']} | {100 * r['stokes_rel_error']:+.3f} % | "
              f"{r['wall_time_s']:.1f} s |")
    for c in out.get("coupled", []):
        print(f"coupled {c['case']}: plateau {c['plateau']['plateau']:.6g} m/s, "
              f"{100 * c['rel_diff_to_frame']:+.3f} % from the frame solve")
    return out


# ------------------------------------------------------------------ checks 2-5
def check_settling(args) -> dict:
    scene, notes = configure(Scene.bundled("settling_disk_channel"), args)
    hist, summary, wall, failure = run_scene(scene)
    p = scene.particles[0]
    d = core_diameter(p)
    s = measures.settling_summary(hist.t, hist.x[:, 0], hist.y[:, 0], hist.vx[:, 0],
                                  hist.vy[:, 0], d, scene.fluid.density, scene.fluid.viscosity)
    lit = load("sedimentation")["checks"]["single_disk_settling"]
    out = {"check": 2, **run_info(scene, summary, wall, failure, notes), "measured": s,
           "literature": {"re_max": lit["re_max"]},
           "history": {"t": hist.t.tolist(), "y": hist.y[:, 0].tolist(),
                       "vy": hist.vy[:, 0].tolist(), "x": hist.x[:, 0].tolist()}}
    print("\n| quantity | measured | literature |\n|---|---|---|")
    print(f"| max Re_p | {s['re_max']:.4g} (t = {s['t_re_max']:.3g} s) | "
          f"{lit['re_max']['status']} (quoted ~{lit['re_max']['quoted_in_issue']}) |")
    print(f"| plateau v_y | {s['plateau']['plateau']:.5g} m/s "
          f"(reached: {s['plateau']['reached']}) | not found |")
    print(f"| final y | {s['y_final'] * 1e3:.3f} mm | not found |")
    print(f"\nmesh {summary.get('mesh')}, {summary.get('steps')} steps, "
          f"{summary.get('remeshes')} remeshes, wall {wall:.1f} s")
    return out


def check_dkt(args) -> dict:
    """Check 3: drafting, kissing and tumbling times (definitions: docs/sedimentation.md)."""
    scene, notes = configure(Scene.bundled(args.dkt_scene), args)
    if args.dkt_x:  # other abscissae of the two centres (the lateral offset)
        from skfem_granular.dem import Polygon

        parts = []
        for p, x in zip(scene.particles, args.dkt_x, strict=True):
            V = p.polygon.vertices
            parts.append(dataclasses.replace(p, polygon=Polygon(
                V + np.array([[x - p.polygon.centroid[0]], [0.0]]))))
        scene = dataclasses.replace(scene, particles=tuple(parts))
        notes.append(f"centres moved to x = {args.dkt_x} m")
    hist, summary, wall, failure = run_scene(scene)
    r = shadow_radius(scene.particles[0])
    m = measures.kiss_tumble_times(hist.t, hist.x, hist.y, r)
    gap, tilt = m.pop("gap"), m.pop("tilt")
    core_gap = gap + 2 * r * (1 - scene.particles[0].core_ratio)
    lead = int(np.argmin(hist.y[0]))
    out = {"check": 3, **run_info(scene, summary, wall, failure, notes), "measured": m,
           "min_core_gap": float(core_gap.min()),
           "max_speed": float(np.hypot(hist.vx, hist.vy).max()),
           "literature": load("sedimentation")["checks"]["drafting_kissing_tumbling"],
           "history": {"t": hist.t.tolist(), "gap": gap.tolist(), "tilt_deg": tilt.tolist(),
                       "y": hist.y.tolist(), "x": hist.x.tolist(), "vx": hist.vx.tolist(),
                       "vy": hist.vy.tolist(), "omega": hist.omega.tolist()},
           "leading_particle": lead}
    print("\n| quantity | measured |\n|---|---|")
    for k in ("t_drafting", "t_kiss", "t_min_gap", "t_tilt45", "t_tumble"):
        print(f"| {k} | {m[k]:.4g} s |")
    print(f"| min shadow gap | {m['min_gap'] * 1e6:.1f} um |")
    print(f"| min core gap | {core_gap.min() * 1e6:.1f} um |")
    print(f"\nstages in order: {m['stages']}; mesh {summary.get('mesh')}, "
          f"{summary.get('remeshes')} remeshes; wall {wall:.1f} s")
    return out


def check_migration(args) -> dict:
    scene, notes = configure(Scene.bundled("migration_off_centre"), args)
    hist, summary, wall, failure = run_scene(scene)
    x0, _, x1, _ = scene.domain
    m = measures.lateral_offset(hist.t, hist.x[:, 0], 0.5 * (x0 + x1), 0.5 * (x1 - x0))
    off = m.pop("offset")
    out = {"check": 4, **run_info(scene, summary, wall, failure, notes), "measured": m,
           "history": {"t": hist.t.tolist(), "offset": off.tolist(),
                       "y": hist.y[:, 0].tolist()}}
    print(f"\noffset / half-width: initial {m['initial']:.3f}, final {m['final']:.4f}, "
          f"below 1 % from t = {m['t_1pc']:.3g} s; wall {wall:.1f} s")
    return out


def long_axis(V) -> float:
    """Angle (rad) of the longest edge of the outline ``V`` (2, n): a rectangle's long axis."""
    e = np.diff(V, axis=1, append=V[:, :1])
    k = int(np.argmax(np.hypot(*e)))
    return float(np.arctan2(e[1, k], e[0, k]))


class MirrorWatch:
    """Samples whether the mesh in use is mirror-symmetric about ``x = x_axis``.

    Called after every step (``run_scene``'s ``on_step``); looks every ``every``
    steps and at every change of the mesh's vertex count (a remesh).
    """

    def __init__(self, x_axis: float, every: int = 20):
        self.x_axis, self.every = x_axis, every
        self.samples, self.n, self._nv = [], 0, None

    def __call__(self, sim, t):
        from skfem_granular.studies import mirror_symmetric

        m = sim.mesh
        self.n += 1
        if self.n % self.every and m.p.shape[1] == self._nv:
            return
        self._nv = m.p.shape[1]
        self.samples.append((float(t), bool(mirror_symmetric(m, 0, self.x_axis))))

    def summary(self) -> dict:
        bad = [t for t, ok in self.samples if not ok]
        return {"samples": len(self.samples), "symmetric": len(self.samples) - len(bad),
                "first_asymmetric_t": bad[0] if bad else None}


def check_shape(args) -> dict:
    """Check 5: the rectangle's long axis turns broadside; the hexagon does not rotate."""
    out = {"check": 5, "runs": []}
    names = [n for n in ("settling_rectangle", "settling_hexagon") if n in args.scenes]
    for name in names:
        scene, notes = configure(Scene.bundled(name), args)
        x0, _, x1, _ = scene.domain
        watch = MirrorWatch(0.5 * (x0 + x1)) if name == "settling_hexagon" else None
        hist, summary, wall, failure = run_scene(scene, watch)
        p = scene.particles[0]
        V = p.polygon.vertices
        row = {**run_info(scene, summary, wall, failure, notes),
               "mesh_motion": "ale" if scene.moving_mesh else "fixed"}
        speed = np.hypot(hist.vx[:, 0], hist.vy[:, 0])
        row["max_speed"] = float(speed.max())
        row["y_final"] = float(hist.y[-1, 0])
        if name == "settling_rectangle":
            ang = measures.axis_orientation(hist.angle[:, 0], long_axis(V))
            L = float(np.hypot(*np.diff(V, axis=1)).max())  # the long side
            row.update(long_side=L, re_max_long_side=float(
                scene.fluid.density * speed.max() * L / scene.fluid.viscosity))
            row["axis_angle_deg"] = {"initial": float(ang[0]), "final": float(ang[-1]),
                                     "max": float(ang.max()),
                                     "t_within_5deg": measures.settled_after(hist.t, ang, 5.0),
                                     "t_within_1deg": measures.settled_after(hist.t, ang, 1.0)}
            row["history"] = {"t": hist.t.tolist(), "axis_angle_deg": ang.tolist(),
                              "y": hist.y[:, 0].tolist(), "vy": hist.vy[:, 0].tolist(),
                              "omega": hist.omega[:, 0].tolist()}
            a = row["axis_angle_deg"]
            print(f"\nrectangle: long axis {a['initial']:.1f} -> {a['final']:.3g} deg from "
                  f"horizontal (0 = broadside), within 5 deg from t = {a['t_within_5deg']:.3g} s, "
                  f"within 1 deg from {a['t_within_1deg']:.3g} s; max speed "
                  f"{row['max_speed']:.4g} m/s (Re_L {row['re_max_long_side']:.3g}); "
                  f"wall {wall:.1f} s", flush=True)
        else:
            R = shadow_radius(p) * p.core_ratio
            row["max_abs_omega"] = float(np.abs(hist.omega[:, 0]).max())
            row["omega_scale"] = float(speed.max() / R)  # U / R
            row["max_abs_vx"] = float(np.abs(hist.vx[:, 0]).max())
            row["max_abs_x_drift"] = float(np.abs(hist.x[:, 0] - hist.x[0, 0]).max())
            row["max_abs_angle"] = float(np.abs(hist.angle[:, 0]).max())
            row["mirror"] = watch.summary()
            row["history"] = {"t": hist.t.tolist(), "omega": hist.omega[:, 0].tolist(),
                              "x": hist.x[:, 0].tolist(), "vy": hist.vy[:, 0].tolist()}
            print(f"hexagon: max |omega| {row['max_abs_omega']:.2e} rad/s "
                  f"(U/R = {row['omega_scale']:.3g}), max |x drift| "
                  f"{row['max_abs_x_drift']:.2e} m, max |v_x| {row['max_abs_vx']:.2e} m/s; "
                  f"mesh mirror-symmetric at {row['mirror']['symmetric']} of "
                  f"{row['mirror']['samples']} samples; wall {wall:.1f} s", flush=True)
        out["runs"].append(row)
    return out


# ------------------------------------------------------------------ check 6
def irregular_grain(center, radius, rng):
    """An elongated convex 4-7-gon (aspect ~0.7) of circumradius <= ``radius`` at ``center``.

    Seven random points on an ellipse of semi-axes ``radius`` and ``0.7 radius``
    (each scaled by 0.85-1), their convex hull, rotated at random; slivers (area
    below ``1.1 radius^2``, half the ellipse's) are drawn again: a sliver's tiny
    mass would cut the stable DEM step by an order of magnitude.
    """
    from scipy.spatial import ConvexHull

    from skfem_granular.dem import Polygon

    while True:
        phi = np.sort(rng.uniform(0, 2 * np.pi, 7))
        pts = np.column_stack([np.cos(phi), 0.7 * np.sin(phi)]) * radius * rng.uniform(
            0.85, 1.0, (7, 1))
        a = rng.uniform(0, np.pi)
        pts = pts @ np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
        V = pts[ConvexHull(pts).vertices].T
        if Polygon(V).area >= 1.1 * radius**2:
            return Polygon(V - Polygon(V).centroid[:, None] + np.asarray(center)[:, None])


def repose_scene(shape: str, seed: int = 3) -> Scene:
    """``repose_hexagons`` with its grains replaced by ``shape`` (``hexagons``,
    ``irregular`` or a number of sides), same centres and size."""
    from skfem_granular.dem import Polygon

    sc = Scene.bundled("repose_hexagons")
    if shape == "hexagons":
        return sc
    rng = np.random.default_rng(seed)
    parts = []
    for p in sc.particles:
        c = p.polygon.centroid
        r = shadow_radius(p)
        poly = (irregular_grain(c, r, rng) if shape == "irregular"
                else Polygon.regular(int(shape), r, center=c, angle=rng.uniform(0, 2 * np.pi)))
        parts.append(dataclasses.replace(p, polygon=poly))
    return dataclasses.replace(sc, particles=tuple(parts), name=f"repose_{shape}")


def check_repose(args) -> dict:
    out = {"check": 6, "runs": [],
           "literature": load("sedimentation")["checks"]["angle_of_repose"]}
    for shape in args.shape:
        sc, notes = configure(repose_scene(shape), args)
        if args.law:
            law = dataclasses.replace(sc.contact_law, **json.loads(args.law))
            sc = dataclasses.replace(sc, contact_law=law)
        hist, summary, wall, failure = run_scene(sc)
        X = np.vstack([hist.x[-1], hist.y[-1]])
        R = np.array([shadow_radius(p) for p in sc.particles])
        a = measures.angle_of_repose(X[0], X[1] + R, column=2.0 * R.mean())
        speed = np.hypot(hist.vx[-1], hist.vy[-1])
        out["runs"].append({"shape": shape, "contact_law": dataclasses.asdict(sc.contact_law),
                            "angle": a, "runout_m": float(np.ptp(X[0])),
                            "max_speed_final": float(speed.max()),
                            **run_info(sc, summary, wall, failure, notes)})
        print(f"  {shape}: {a['left']:.1f} / {a['right']:.1f} deg (mean {a['mean']:.1f}), "
              f"height {a['height'] * 1e3:.2f} mm, wall {wall:.1f} s", flush=True)
    print("\n| grains | n | mu | angle left | angle right | mean | literature | wall |")
    print("|---|---|---|---|---|---|---|---|")
    for r in out["runs"]:
        a = r["angle"]
        print(f"| {r['shape']} | {len(Scene.bundled('repose_hexagons').particles)} | "
              f"{r['contact_law']['mu']} | {a['left']:.1f} | {a['right']:.1f} | "
              f"{a['mean']:.1f} | not found | {r['wall_time_s']:.0f} s |")
    return out


# ------------------------------------------------------------------ check 7
def check_cost(args) -> dict:
    from skfem_granular.studies import settling, settling_plots

    out = ROOT / "out" / f"study_settling{'_smoke' if args.smoke else ''}"
    t0 = time.perf_counter()
    rows = settling.run(out, smoke=args.smoke, log=lambda m: print("  " + m, flush=True))
    wall = time.perf_counter() - t0
    table = settling.table(rows)
    print("\n" + table)
    fronts = {q: [r["key"] for r in settling.front(rows, q)] for q in settling.QUANTITIES}
    result = {"check": 7, "study": "settling", "smoke": args.smoke, "rows": rows,
              "pareto_front": fronts, "runs_computed": sum(r["computed"] for r in rows),
              "wall_time_study_s": round(wall, 1),
              "sum_of_run_wall_times_s": round(sum(r["wall"] for r in rows), 1)}
    old = RESULTS / f"sedimentation_cost{'_' + args.tag if args.tag else ''}.json"
    if not result["runs_computed"] and old.exists():  # all resumed: keep the timing
        result["wall_time_study_s"] = json.loads(old.read_text())["wall_time_study_s"]
        result["note"] = "records resumed; wall_time_study_s of the run that computed them"
    if not args.smoke:
        (RESULTS / "study_settling.md").write_text(
            "# settling study\n\n" + table + "\n")
        figs = ROOT / "docs" / "figures"
        settling_plots.plot_pareto(rows, figs / "study_settling_pareto.png")
        settling_plots.plot_convergence(rows, figs / "study_settling_convergence.png")
    return result


# ------------------------------------------------------------------ main
def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", choices=CHECKS, required=True)
    ap.add_argument("--t-end", type=float)
    ap.add_argument("--dt", type=float)
    ap.add_argument("--adaptive", action="store_true")
    ap.add_argument("--tol", type=float)
    ap.add_argument("--delta-l", type=float)
    ap.add_argument("--sigma", type=float)
    ap.add_argument("--remesh-fraction", type=float)
    ap.add_argument("--remesh-travel", type=float)
    ap.add_argument("--mesh-motion", choices=("ale", "fixed"))
    ap.add_argument("--coupled", action="store_true",
                    help="terminal: also run the free-settling scenes (long)")
    ap.add_argument("--shape", nargs="+", default=["hexagons", "irregular", "24"],
                    help="repose: grain shapes (hexagons, irregular, or a number of sides)")
    ap.add_argument("--dkt-scene", default="dkt_two_disks",
                    help="dkt: the bundled scene (dkt_uhlmann: Uhlmann's set-up)")
    ap.add_argument("--dkt-x", type=float, nargs=2,
                    help="dkt: the abscissae (m) of the lower and the upper disk's centres")
    ap.add_argument("--scenes", nargs="+", default=["settling_rectangle", "settling_hexagon"],
                    help="shape: which of the two scenes to run")
    ap.add_argument("--law", help='repose: contact-law overrides as JSON, e.g. \'{"gamma": 1}\'')
    ap.add_argument("--smoke", action="store_true", help="cost: the smoke grid")
    ap.add_argument("--out", help="output directory of the runs (default: none written)")
    ap.add_argument("--tag", help="suffix of the JSON file name")
    args = ap.parse_args(argv)
    fn = {"terminal": check_terminal, "settling": check_settling, "dkt": check_dkt,
          "migration": check_migration, "shape": check_shape, "repose": check_repose,
          "cost": check_cost}[args.check]
    t0 = time.perf_counter()
    print(f"sedimentation --check {args.check}", flush=True)
    result = fn(args)
    result.update({"benchmark": f"sedimentation_{args.check}", "machine": platform.platform(),
                   "python": sys.version.split()[0], "argv": sys.argv[1:],
                   "wall_time_total_s": round(time.perf_counter() - t0, 2)})
    name = f"sedimentation_{args.check}" + (f"_{args.tag}" if args.tag else "") + ".json"
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / name).write_text(json.dumps(result, indent=1, default=float))
    print(f"\nwrote benchmarks/results/{name} ({result['wall_time_total_s']:.1f} s)")


if __name__ == "__main__":
    main()
