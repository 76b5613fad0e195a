"""Accuracy against cost on a moving case: the settling disk of the sedimentation checks.

The scene is ``settling_disk_channel`` (Glowinski et al. 2001; Wan & Turek
2006: a 2.5 mm disk, 1250 kg/m^3, released at rest in a closed 2 cm x 6 cm
channel of a fluid of 1000 kg/m^3 and 0.01 Pa s). Two quantities:

- ``re_max``: the maximum particle Reynolds number ``rho_f |v| d / mu``
  (``d`` the disk the fluid sees);
- ``t_fall``: the settling time, the first time the centre has fallen
  ``fall`` below its start (linear interpolation between steps). The full
  study's ``fall`` is 36.25 mm: down to one diameter's gap above the floor.

The axes (:func:`plan`), each varied alone from the base discretisation (the
scene's graded mesh: outline edge ``delta_l`` = 0.245 mm, Eq. 4's
``sigma = 1 + delta_l / r0`` = 1.196, ``dt`` = 1 ms, ``remesh`` = 1):

- ``delta_l``: outline resolution (the graded mesh's first ring);
- ``sigma``: the graded mesh's growth factor;
- ``dt``: the time step;
- ``remesh``: the remesh threshold of the mesh motion (``"ale"``:
  ``remesh_travel``, radii travelled from where the mesh was graded;
  ``"fixed"``: ``remesh_fraction``, the fraction of an outline edge the body
  may move before a remesh; the two are different rules, so their values
  are not comparable);
- ``motion``: the mesh-motion scheme, ``"ale"`` or ``"fixed"`` (each axis is
  run for both where the grid says so).

Errors: the mesh and remesh rows against the finest-mesh run of the study
(``delta_l`` smallest, ``"ale"``, named in the ``reference`` column); the
``dt`` rows against the smallest step of the same motion on the base mesh (a
step-only error). Runs go one at a time in this process (``run``), each
record kept in ``<out>/runs/<key>.json`` as it finishes; a rerun resumes.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from ..io import write_text
from .analysis import pareto_front

SCENE_NAME = "settling_disk_channel"
E0 = 2 * 1.25e-3 * math.sin(math.pi / 32)  # the scene's outline edge (32-gon, r = 1.25 mm)
FALL = 40e-3 - 1.5 * 2.5e-3  # from y = 40 mm to one diameter's gap above the floor
QUANTITIES = ("re_max", "t_fall")


@dataclass(frozen=True)
class SettlingRun:
    """One discretisation of the settling study (``None``: the scene's value)."""

    family: str  # "base" | "delta_l" | "sigma" | "dt" | "remesh"
    motion: str = "ale"  # "ale" | "fixed"
    delta_l: float | None = None
    sigma: float | None = None
    dt: float = 1e-3
    remesh: float | None = None
    t_end: float = 0.8
    fall: float = FALL

    @property
    def key(self) -> str:
        parts = [self.family, self.motion]
        for name in ("delta_l", "sigma", "dt", "remesh", "t_end"):
            v = getattr(self, name)
            if v is not None:
                parts.append(f"{name}{v:.4g}")
        return "_".join(parts)

    def scene(self):
        """The bundled scene with this run's discretisation."""
        from ..scene import MeshSpec, Scene, TimeSpec

        sc = Scene.bundled(SCENE_NAME)
        sc = replace(sc, output_dir=None, mesh_motion=self.motion,
                     mesh=MeshSpec("graded", self.delta_l, self.sigma),
                     time=TimeSpec(t_end=self.t_end, dt=self.dt))
        if self.remesh is not None:
            field = "remesh_travel" if self.motion == "ale" else "remesh_fraction"
            sc = replace(sc, **{field: self.remesh})
        return sc


def plan(smoke: bool = False) -> list[SettlingRun]:
    """The runs: each axis varied alone from the base, for the motions the grid names.

    The graded mesher splits every outline edge into ``ceil(edge / delta_l)``
    equal pieces and grades from the pieces' length (a ``delta_l`` above the
    edge gives the scene's mesh, 0.8 and 0.5 of it the same mesh), so the
    outline axis has the levels edge / n: 1/2 and 1/3 of the edge here (1809
    and 3972 vertices at release, against 492). The fixed mesh
    remeshes about every step at full speed (a quarter of an edge is 0.06 mm,
    the disk falls 0.056 mm per ms), so it is not refined.
    ``smoke``: 6 ms in steps of 2 ms, ``fall`` 0.01 mm (seconds in all).
    """
    if smoke:
        kw = {"t_end": 0.006, "fall": 1e-5, "dt": 2e-3}
        runs = [SettlingRun("base", m, **kw) for m in ("ale", "fixed")]
        runs += [SettlingRun("delta_l", "ale", delta_l=0.8 * E0, **kw),
                 SettlingRun("sigma", "ale", sigma=1.4, **kw),
                 SettlingRun("dt", "ale", **(kw | {"dt": 1e-3})),
                 SettlingRun("remesh", "fixed", remesh=0.5, **kw)]
        return runs
    runs = [SettlingRun("base", m) for m in ("ale", "fixed")]
    runs += [SettlingRun("delta_l", "ale", delta_l=f * E0) for f in (0.5, 0.34)]
    runs += [SettlingRun("sigma", "ale", sigma=s) for s in (1.1, 1.3, 1.45)]
    runs += [SettlingRun("dt", m, dt=dt) for m in ("ale", "fixed") for dt in (2e-3, 5e-4)]
    runs += [SettlingRun("remesh", "ale", remesh=r) for r in (0.5, 2.0, 4.0)]
    runs += [SettlingRun("remesh", "fixed", remesh=r) for r in (0.5, 1.0)]
    return runs


AXES = ("delta_l", "sigma", "dt", "remesh")


def axis_values(run: SettlingRun) -> dict:
    """The run's value on every axis, the scene's defaults filled in (``delta_l``: the
    length of the outline pieces the mesher makes of it)."""
    d = E0 / math.ceil(E0 / run.delta_l - 1e-9) if run.delta_l else E0  # the pieces' length
    return {"delta_l": d, "sigma": run.sigma or 1 + d / 1.25e-3, "dt": run.dt,
            "remesh": run.remesh if run.remesh is not None else (1.0 if run.motion == "ale"
                                                                  else 0.25)}


def execute(run: SettlingRun) -> dict:
    """Compute one run; returns a JSON-able record."""
    from ..simulation import Simulation
    from ..validation.measures import settling_summary

    sc = run.scene()
    t0 = time.perf_counter()
    sim = Simulation(sc)
    start = {"vertices": int(sim.mesh.p.shape[1]), "dofs": int(sim.space.N)}
    res = sim.run(progress=False)
    wall = time.perf_counter() - t0
    h, s = res.history, res.summary
    if h.t[-1] < run.t_end - 0.5 * run.dt:  # stopped by a signal: no record
        raise RuntimeError(f"{run.key}: stopped at t = {h.t[-1]:.6g} s, before t_end")
    p = sc.particles[0]
    V = p.polygon.vertices
    d = 2 * float(np.hypot(*(V - p.polygon.centroid[:, None])).max()) * p.core_ratio
    m = settling_summary(h.t, h.x[:, 0], h.y[:, 0], h.vx[:, 0], h.vy[:, 0], d,
                         sc.fluid.density, sc.fluid.viscosity)
    return {"key": run.key, "spec": asdict(run), "vertices": start["vertices"],
            "dofs": start["dofs"], "final_mesh": s["mesh"], "remeshes": s.get("remeshes"),
            "steps": s.get("steps"),
            "wall": wall, "wall_phases": s.get("wall_time"), "re_max": m["re_max"],
            "t_re_max": m["t_re_max"], "t_fall": fall_time(h.t, h.y[:, 0], run.fall),
            "max_drift": m["max_drift"], "t": h.t.tolist(), "vy": h.vy[:, 0].tolist()}


def fall_time(t, y, fall: float) -> float:
    """First time ``y`` is ``fall`` below ``y[0]`` (linear between samples; NaN if never)."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    below = np.flatnonzero(y <= y[0] - fall)
    if below.size == 0:
        return float("nan")
    k = int(below[0])
    if k == 0:
        return float(t[0])
    y1 = y[0] - fall
    return float(t[k - 1] + (t[k] - t[k - 1]) * (y1 - y[k - 1]) / (y[k] - y[k - 1]))


def run(out_dir, smoke: bool = False, runs=None, log=print) -> list[dict]:
    """Run (or resume) the study into ``out_dir``; returns :func:`analyse`'s rows."""
    runs = plan(smoke) if runs is None else list(runs)
    rdir = Path(out_dir) / "runs"
    rdir.mkdir(parents=True, exist_ok=True)
    records, computed = {}, set()
    for r in runs:
        path = rdir / f"{r.key}.json"
        if path.exists():
            rec = json.loads(path.read_text())
            if rec.get("spec") == asdict(r):
                records[r.key] = rec
                continue
        rec = execute(r)
        computed.add(r.key)
        write_text(path, json.dumps(rec))
        records[r.key] = rec
        if log:
            log(f"{r.key}: {rec['dofs']} DOFs, {rec['remeshes']} remeshes, re_max "
                f"{rec['re_max']:.6g}, t_fall {rec['t_fall']:.6g} s, {rec['wall']:.1f} s")
    rows = analyse(runs, records)
    for row in rows:
        row["computed"] = row["key"] in computed
    return rows


def reference(runs, run: SettlingRun) -> SettlingRun:
    """The run ``run``'s errors are measured against (see the module notes)."""
    if run.family == "dt":
        same = [r for r in runs if r.motion == run.motion and r.family in ("dt", "base")
                and r.delta_l == run.delta_l and r.sigma is None and r.remesh is None]
        return min(same, key=lambda r: r.dt)
    mesh = [r for r in runs if r.motion == "ale" and r.family in ("delta_l", "base")]
    return min(mesh, key=lambda r: axis_values(r)["delta_l"])


def analyse(runs, records) -> list[dict]:
    """One row per finished run: values, errors against the reference, cost
    (``vertices`` and ``dofs`` of the mesh at release; the run remeshes).

    ``error_<q>`` is against the run's :func:`reference`; the base and ``dt``
    rows also have ``error_dt_<q>``, against the smallest step of their motion
    (the step-only error drawn on the ``dt`` axis).
    """
    rows = []
    for r in runs:
        rec = records.get(r.key)
        if rec is None:
            continue
        ref = reference(runs, r)
        row = {"key": r.key, "family": r.family, "motion": r.motion, "axes": axis_values(r),
               "delta_l": r.delta_l, "sigma": r.sigma, "dt": r.dt, "remesh": r.remesh,
               "vertices": rec["vertices"], "dofs": rec["dofs"], "remeshes": rec["remeshes"],
               "wall": rec["wall"], "reference": ref.key}
        refs = {"": ref}
        if r.family in ("dt", "base"):  # the step-only error, for the dt axis
            refs["dt_"] = reference(runs, replace(r, family="dt"))
        for q in QUANTITIES:
            row[q] = rec[q]
            for pre, rf in refs.items():
                rr = records.get(rf.key)
                row[f"error_{pre}{q}"] = (float("nan") if rr is None or rf.key == r.key
                                          else abs(rec[q] / rr[q] - 1))
        rows.append(row)
    return rows


def front(rows, q: str) -> list[dict]:
    """The Pareto front (wall time, error in ``q``) of the rows measured against the
    finest mesh (the ``dt`` rows have another reference and are left out)."""
    sel = [r for r in rows if r["family"] != "dt" and np.isfinite(r[f"error_{q}"])
           and r[f"error_{q}"] > 0]
    return [sel[i] for i in pareto_front([(r["wall"], r[f"error_{q}"]) for r in sel])]


def table(rows) -> str:
    """The rows as a markdown table."""
    cols = ("family", "motion", "axis", "vertices", "dofs", "remeshes", "wall", "re_max",
            "error_re_max", "t_fall", "error_t_fall")
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in rows:
        v = r | {"axis": r["axes"].get(r["family"], "")}
        lines.append("| " + " | ".join(_fmt(v[c]) for c in cols) + " |")
    return "\n".join(lines)


def _fmt(v):
    if isinstance(v, float):
        return "nan" if math.isnan(v) else f"{v:.6g}"
    return str(v)
