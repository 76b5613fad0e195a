"""Accuracy against cost: one scene over a grid of discretisations.

Two studies:

``"single-particle"``
    The paper's sinking particle (``scenes/single_particle.toml``, 24-gon):
    uniform meshes at several ``h``, graded meshes at several outline
    resolutions ``delta_l`` and growth factors ``sigma``, several time steps.
    Quantities: ``v_y(t_end)`` and the whole ``v_y`` curve (max deviation).
    No analytic value: errors are against the finest run of the study, named
    in the ``reference`` column (the finest uniform mesh for the mesh
    families, the smallest step on the base graded mesh for the step family).
``"faxen"``
    Steady Stokes drag on a disk (radius 0.2) moving along the centre line of
    a closed channel ``[-3, 3] x [-1, 1]`` (k = 0.2, VALIDATION.md case 3),
    regular n-gons with growing n. Errors are against the analytic Faxen value
    for the *circle*, so they include the polygonal outline's error.

Rounding error, two measures, each named in the table:

- ``mirror``: on a mirror-symmetric mesh with the particle on the symmetry
  line, the force/velocity across the line is rounding alone
  (``|v_x| / |v_y|``, ``|F_y| / |F_x|``); NaN on meshes that are not symmetric;
- ``renumber``: the spread (max - min over the unpermuted run and runs whose
  nodes and elements are randomly renumbered, :func:`renumbered`) of the
  quantity, relative to its size, on any mesh.

Runs are independent tasks on a :class:`concurrent.futures.Executor` (default:
a local process pool, a fresh process per run so its peak memory is its own),
each written to ``<out>/runs/<key>.json`` as it finishes; a rerun skips runs
whose file is there (resume). Tables and plots: :mod:`.study_plots`.
"""

from __future__ import annotations

import json
import math
import os
import resource
import time
from concurrent.futures import Executor, as_completed
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from .scene import bundled

STUDIES = ("single-particle", "faxen")
SCENE = bundled("single_particle")
FAXEN = {"box": (-3.0, -1.0, 3.0, 1.0), "a": 0.2, "l": 1.0}
COLUMNS = ("key", "family", "kind", "n_sides", "h", "delta_l", "sigma", "dt", "seed",
           "vertices", "p2_nodes", "dofs", "wall_time", "wall_meshing", "wall_assembly",
           "wall_solve", "wall_other", "peak_rss_mb", "quantity", "value", "reference",
           "reference_value", "error", "error_curve", "mirror_symmetric", "rounding_mirror",
           "rounding_renumber", "rounding_field")


@dataclass(frozen=True)
class Run:
    """One discretisation of a study (``seed``: node renumbering, 0 = none)."""

    family: str  # "uniform" | "graded" | "sigma" | "dt"
    kind: str  # mesh kind
    h: float | None = None
    delta_l: float | None = None
    sigma: float | None = None
    dt: float | None = None
    n_sides: int | None = None
    t_end: float | None = None
    seed: int = 0

    @property
    def key(self) -> str:
        parts = [self.family, self.kind]
        for name in ("n_sides", "h", "delta_l", "sigma", "dt", "t_end"):
            v = getattr(self, name)
            if v is not None:
                parts.append(f"{name}{v:g}")
        if self.seed:
            parts.append(f"perm{self.seed}")
        return "_".join(parts)

    @property
    def mesh_key(self) -> str:
        """The key of the unpermuted run on the same mesh and step."""
        return replace(self, seed=0).key


def plan(study: str, smoke: bool = False) -> list[Run]:
    """The runs of ``study``; ``smoke`` gives a small grid of short runs (minutes in all)."""
    if study not in STUDIES:
        raise ValueError(f"study = {study!r}: must be one of {', '.join(STUDIES)}")
    if study == "faxen":
        return _plan_faxen(smoke)
    e = 2 * 0.5e-3 * math.sin(math.pi / 24)  # the scene's 24-gon outline edge
    dt0, t_end = 1e-5, (1e-4 if smoke else None)
    if smoke:
        uni = [(0.26e-3, None), (e, None)]
        gra = [(None, None), (None, 1.5), (e / 2, None)]
        dts = (2e-5, 1e-5, 5e-6)
        seeds = {"graded": [None], "uniform": [0.26e-3]}
        n_seeds = 2
    else:
        uni = [(0.2e-3, None), (e, None), (e / 2, e / 2)]
        gra = [(dl, s) for dl in (None, e / 2) for s in (None, 1.15, 1.5)]
        dts = (4e-5, 2e-5, 1e-5, 5e-6, 2.5e-6)
        seeds = {"graded": [None, e / 2], "uniform": [0.2e-3, e]}
        n_seeds = 3
    runs = [Run("uniform", "uniform", h=h, delta_l=dl, dt=dt0, t_end=t_end) for h, dl in uni]
    runs += [Run("graded" if s is None else "sigma", "graded", delta_l=dl, sigma=s, dt=dt0,
                 t_end=t_end) for dl, s in gra]
    runs += [Run("dt", "graded", dt=dt, t_end=t_end) for dt in dts if dt != dt0]
    for r in list(runs):
        if r.family in ("uniform", "graded") and (r.h if r.family == "uniform" else r.delta_l) \
                in seeds[r.family]:
            runs += [replace(r, seed=k) for k in range(1, n_seeds + 1)]
    return runs


def _plan_faxen(smoke):
    ns_g = (12, 24, 48) if smoke else (12, 16, 24, 32, 48, 64, 96, 128)
    ns_s = (12, 24, 48) if smoke else (12, 24, 48, 96, 128)
    ns_u = (12, 16) if smoke else (12, 16, 24, 32)
    runs = [Run("graded", "graded", n_sides=n) for n in ns_g]
    runs += [Run("sigma", "graded", n_sides=n, sigma=s) for s in (1.2, 1.5) if not smoke or s == 1.5
             for n in ns_s]
    runs += [Run("uniform", "uniform", n_sides=n) for n in ns_u]
    n_seeds = 2 if smoke else 3
    runs += [replace(r, seed=k) for r in list(runs) if r.family != "sigma"
             for k in range(1, n_seeds + 1)]
    return runs


def faxen_drag(k: float) -> float:
    """Faxen's F/(mu U) for a cylinder on the centre line of a closed channel (k = a/l)."""
    s = math.log(1 / k) - 0.9157 + 1.7244 * k**2 - 1.7302 * k**4 + 2.4056 * k**6 - 4.5913 * k**8
    return 4 * math.pi / s


# ------------------------------------------------------------------ mesh helpers
def renumbered(mesh, seed: int):
    """The same mesh with nodes and elements randomly renumbered (same named boundaries)."""
    import skfem

    rng = np.random.default_rng(seed)
    n = mesh.p.shape[1]
    perm = rng.permutation(n)  # new node j is old node perm[j]
    new = np.empty(n, dtype=np.int64)
    new[perm] = np.arange(n)
    t = new[mesh.t][:, rng.permutation(mesh.t.shape[1])]
    t = np.roll(t, int(rng.integers(3)), axis=0)  # a cyclic shift keeps the orientation
    m = skfem.MeshTri(np.ascontiguousarray(mesh.p[:, perm]), np.ascontiguousarray(t), sort_t=False)
    f = np.sort(m.facets, axis=0).astype(np.int64)
    fkey = f[0] * n + f[1]
    order = np.argsort(fkey)
    bnd = {}
    for name, facets in mesh.boundaries.items():
        g = np.sort(new[mesh.facets[:, facets]], axis=0)
        bnd[name] = order[np.searchsorted(fkey, g[0] * n + g[1], sorter=order)]
    out = skfem.MeshTri(m.p, m.t, _boundaries=bnd, sort_t=False)
    for attr in ("particle_nodes", "meshing_recipe"):
        if hasattr(mesh, attr):
            v = getattr(mesh, attr)
            setattr(out, attr, [new[a] for a in v] if attr == "particle_nodes" else v)
    return out


def mirror_symmetric(mesh, axis: int, value: float, tol: float = 1e-9) -> bool:
    """Whether the mesh maps onto itself under reflection at ``x[axis] = value``."""
    from scipy.spatial import cKDTree

    p = mesh.p
    q = p.copy()
    q[axis] = 2 * value - q[axis]
    scale = float(np.ptp(p, axis=1).max())
    d, idx = cKDTree(p.T).query(q.T)
    if d.max() > tol * scale:
        return False
    mapped = np.sort(idx[mesh.t], axis=0)
    orig = np.sort(mesh.t, axis=0)
    return {tuple(c) for c in mapped.T.tolist()} == {tuple(c) for c in orig.T.tolist()}


# ------------------------------------------------------------------ one run (worker side)
def _rss_mb() -> float:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def execute(study: str, run: Run) -> dict:
    """Compute one run; returns a JSON-able record (the worker function)."""
    base = _rss_mb() if os.path.exists("/proc/self/statm") else float("nan")
    t0 = time.perf_counter()
    rec = _execute_faxen(run) if study == "faxen" else _execute_particle(run)
    rec.update(key=run.key, study=study, spec=asdict(run), host_pid=os.getpid(),
               elapsed=time.perf_counter() - t0, base_rss_mb=base,
               peak_rss_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
    return rec


def _execute_faxen(run):
    import meshing
    import skfem_granular as sg
    from skfem_granular.dem import Polygon

    t0 = time.perf_counter()
    disk = Polygon.regular(run.n_sides, FAXEN["a"], center=(0.0, 0.0)).vertices
    if run.kind == "graded":
        mesh = meshing.graded_mesh(FAXEN["box"], [disk], sigma=run.sigma)
    else:
        mesh = meshing.uniform_mesh(FAXEN["box"], [disk], h=run.h)
    if run.seed:
        mesh = renumbered(mesh, run.seed)
    t1 = time.perf_counter()
    space = sg.TaylorHood(mesh)
    t2 = time.perf_counter()
    flow = sg.solve_steady(space, sg.Fluid(1.0, 1.0), {"wall": (0, 0), "particle0": (1.0, 0.0)})
    t3 = time.perf_counter()
    F = flow.force("particle0")
    t4 = time.perf_counter()
    s = np.linspace(-0.9, 0.9, 37)  # fixed probe points: the field, whatever the numbering
    pts = np.hstack([np.vstack([0.5 + 0 * s, s]), np.vstack([2 * s, 0.5 + 0 * s])])
    st = meshing.mesh_stats(mesh)
    return {"vertices": st.n_vertices, "p2_nodes": st.n_p2_nodes, "dofs": int(space.N),
            "wall": {"meshing": t1 - t0, "assembly": t2 - t1, "solve": t3 - t2,
                     "other": t4 - t3, "total": t4 - t0},
            "quantity": "F_x/(mu U)", "value": float(-F[0]), "cross": float(abs(F[1] / F[0])),
            "probe_p": flow.pressure(pts).tolist(),
            "mirror_symmetric": mirror_symmetric(mesh, 1, 0.0)}


def _execute_particle(run):
    from unittest import mock

    import skfem_granular.simulation as simmod
    from skfem_granular.scene import MeshSpec, Scene, TimeSpec

    scene = Scene.from_toml(SCENE)
    t_end = run.t_end or scene.time.t_end
    scene = replace(scene, output_dir=None, mesh=MeshSpec(run.kind, run.delta_l, run.sigma, run.h),
                    time=TimeSpec(t_end=t_end, dt=run.dt))
    build = simmod.build_mesh
    # No mesh= hook in Simulation: renumbering patches the builder the constructor calls
    # (the particle moves < 1 % of an outline edge in 1 ms, so no remesh undoes it).
    with mock.patch.object(simmod, "build_mesh",
                           lambda sc, cores: renumbered(build(sc, cores), run.seed)
                           if run.seed else build(sc, cores)):
        sim = simmod.Simulation(scene, output_dir=None)
    res = sim.run(progress=False)
    s, h = res.summary, res.history
    ph = s["wall_time"]
    wt = {k: ph.get(k, 0.0) for k in ("meshing", "assembly", "total")}
    wt["solve"] = ph.get("factorization", 0.0) + ph.get("solve", 0.0)
    wt["other"] = wt["total"] - wt["meshing"] - wt["assembly"] - wt["solve"]
    cx = 0.5 * (scene.domain[0] + scene.domain[2])
    return {"vertices": s["mesh"]["vertices"], "p2_nodes": s["mesh"]["p2_nodes"],
            "dofs": s["mesh"]["dofs"], "wall": wt, "wall_phases": s["wall_time"],
            "quantity": "v_y(t_end) [m/s]", "value": float(h.vy[-1, 0]),
            "t": h.t.tolist(), "vy": h.vy[:, 0].tolist(),
            "cross": float(np.abs(h.vx[:, 0]).max() / np.abs(h.vy[:, 0]).max()),
            "x_drift": float(h.x[-1, 0] - scene.particles[0].polygon.vertices[0].mean()),
            "mirror_symmetric": mirror_symmetric(sim.mesh, 0, cx), "t_end": t_end}


# ------------------------------------------------------------------ the study (client side)
@dataclass
class StudyResult:
    """Rows of the table, the files written and which runs were computed this time."""

    study: str
    out_dir: Path
    rows: list
    computed: list
    failed: dict
    files: list


def _record_path(out_dir: Path, run: Run) -> Path:
    return out_dir / "runs" / f"{run.key}.json"


def load_records(out_dir, runs) -> dict:
    """Finished records of ``runs`` found in ``out_dir/runs`` (key -> record)."""
    out = {}
    for r in runs:
        p = _record_path(Path(out_dir), r)
        if p.exists():
            try:
                rec = json.loads(p.read_text())
            except json.JSONDecodeError:
                continue  # a torn file from an interrupted write: recompute
            if rec.get("spec") == asdict(r):
                out[r.key] = rec
    return out


def run_study(study: str, out_dir, *, smoke: bool = False, executor: Executor | None = None,
              workers: int = 2, plots: bool = True, log=None, runs=None) -> StudyResult:
    """Run (or resume) ``study`` into ``out_dir``; table, plots and per-run JSON.

    Parameters
    ----------
    executor : concurrent.futures.Executor, optional
        Where the runs go, e.g. ``dask.distributed.Client(...).get_executor()``;
        default a local process pool of ``workers`` processes, a fresh one per run.
    runs : list of Run, optional
        A subset (or another grid) instead of :func:`plan`'s.
    """
    runs = plan(study, smoke) if runs is None else list(runs)
    if not isinstance(workers, int) or isinstance(workers, bool) or workers < 1:
        raise ValueError(f"workers = {workers!r}: must be an integer >= 1")
    out_dir = Path(out_dir)
    (out_dir / "runs").mkdir(parents=True, exist_ok=True)
    done = load_records(out_dir, runs)
    todo = [r for r in runs if r.key not in done]
    computed, failed = [], {}
    own = None
    if todo and executor is None:
        own = executor = _local_pool(workers)
    try:
        futs = {executor.submit(execute, study, r): r for r in todo}
        for fut in as_completed(futs):
            r = futs[fut]
            try:
                rec = fut.result()
            except Exception as exc:  # noqa: BLE001 - one failed run must not lose the others
                failed[r.key] = f"{type(exc).__name__}: {exc}"
                continue
            _write_json(_record_path(out_dir, r), rec)
            done[r.key] = rec
            computed.append(r.key)
            if log:
                log(f"{r.key}: {rec['dofs']} DOFs, {rec['wall']['total']:.2f} s")
    finally:
        if own is not None:
            own.shutdown(wait=True, cancel_futures=True)
    rows = analyse(study, runs, done)
    from . import study_plots

    files = study_plots.write_tables(rows, out_dir, study, smoke)
    if plots and rows:
        files += study_plots.all_plots(rows, out_dir, study)
    return StudyResult(study, out_dir, rows, computed, failed, files)


def _local_pool(workers):
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(["skfem_granular.studies", "skfem_granular.simulation", "meshing"])
    return ProcessPoolExecutor(workers, mp_context=ctx, max_tasks_per_child=1)


def _write_json(path, rec):
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(rec, indent=1))
    os.replace(tmp, path)


def _ref_key(study, runs, run):
    """The key of ``run``'s reference run (None: the analytic value)."""
    if study == "faxen":
        return None
    if run.family == "dt":
        pool = [r for r in runs if r.family in ("dt", "graded") and r.delta_l is None
                and not r.seed and r.sigma is None]
        return min(pool, key=lambda r: r.dt).key
    uni = [r for r in runs if r.family == "uniform" and not r.seed]
    return min(uni, key=lambda r: (r.delta_l or r.h, r.h)).key


def analyse(study, runs, records) -> list[dict]:
    """Table rows: one per finished run, errors against the reference and rounding measures."""
    rows = []
    for r in runs:
        rec = records.get(r.key)
        if rec is None:
            continue
        ref = _ref_key(study, runs, r)
        row = {c: None for c in COLUMNS}
        row.update({k: v for k, v in asdict(r).items() if k in COLUMNS})
        row.update(key=r.key, vertices=rec["vertices"], p2_nodes=rec["p2_nodes"], dofs=rec["dofs"],
                   wall_time=rec["wall"]["total"], peak_rss_mb=rec["peak_rss_mb"],
                   quantity=rec["quantity"], value=rec["value"],
                   mirror_symmetric=rec["mirror_symmetric"])
        for ph in ("meshing", "assembly", "solve", "other"):
            row[f"wall_{ph}"] = rec["wall"].get(ph, 0.0)
        if ref is None:
            k = FAXEN["a"] / FAXEN["l"]
            row.update(reference=f"analytic Faxen (circle, k = {k:g})",
                       reference_value=faxen_drag(k))
            row["error"] = abs(rec["value"] / row["reference_value"] - 1)
        elif ref in records:
            rr = records[ref]
            row.update(reference=f"finest run {ref}", reference_value=rr["value"])
            row["error"] = abs(rec["value"] / rr["value"] - 1)
            vy_ref = np.interp(rec["t"], rr["t"], rr["vy"])
            row["error_curve"] = float(np.abs(np.asarray(rec["vy"]) - vy_ref).max()
                                       / np.abs(rr["vy"]).max())
            if ref == r.key:
                row["error"] = row["error_curve"] = float("nan")  # the reference itself
        row["rounding_mirror"] = rec["cross"] if rec["mirror_symmetric"] else float("nan")
        rows.append(row)
    by_key = {row["key"]: row for row in rows}
    for r in runs:  # renumbering spread, on the unpermuted row
        if r.seed or r.key not in by_key:
            continue
        same = [records[q.key] for q in runs if q.mesh_key == r.key and q.key in records]
        if len(same) < 2:
            continue
        if "vy" in same[0]:  # the whole v_y curve: max over t of the spread, / max |v_y|
            vy = np.array([s["vy"] for s in same])
            spread = np.ptp(vy, axis=0).max() / np.abs(vy).max()
        else:
            vals = [s["value"] for s in same]
            spread = np.ptp(vals) / abs(np.mean(vals))
            pp = np.array([s["probe_p"] for s in same])
            by_key[r.key]["rounding_field"] = float(np.ptp(pp, axis=0).max() / np.abs(pp).max())
        by_key[r.key]["rounding_renumber"] = float(spread)
    return rows
