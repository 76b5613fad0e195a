"""One run of a study, computed where it is sent (a worker process): :func:`execute`.

The record is JSON-able: mesh counts, wall times per phase, peak memory, the
quantity and what the rounding measures need (cross-stream ratio, probe
values or the whole ``v_y`` curve).
"""

from __future__ import annotations

import os
import resource
import time
from dataclasses import asdict, replace

import numpy as np

from .definitions import FAXEN, SCENE, Run
from .meshes import mirror_symmetric, renumbered


def _rss_mb() -> float:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


#: The warm-up of a worker process: a coarse run of each study through the same code
#: (imports, compiled kernels loaded from numba's cache, scikit-fem's element tables),
#: timed apart so that a run's cost is what a user pays for it in a warm session.
WARMUP = {"faxen": Run("graded", "graded", n_sides=12),
          "single-particle": Run("graded", "graded", delta_l=0.2e-3, dt=1e-5, t_end=2e-5)}

_warm: set = set()


def execute(study: str, run: Run) -> dict:
    """Compute one run; returns a JSON-able record (the worker function).

    The first run of a study in a process is preceded by :data:`WARMUP` (``warmup``:
    its wall time, not in ``wall``)."""
    base = _rss_mb() if os.path.exists("/proc/self/statm") else float("nan")
    warmup = 0.0
    if study not in _warm:
        t0 = time.perf_counter()
        _compute(study, WARMUP[study])
        warmup = time.perf_counter() - t0
        _warm.add(study)
    t0 = time.perf_counter()
    rec = _compute(study, run)
    rec.update(key=run.key, study=study, spec=asdict(run), host_pid=os.getpid(),
               elapsed=time.perf_counter() - t0, warmup=warmup, base_rss_mb=base,
               peak_rss_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
    return rec


def _compute(study: str, run: Run) -> dict:
    return _execute_faxen(run) if study == "faxen" else _execute_particle(run)


def _execute_faxen(run):
    import meshing

    from ..dem import Polygon
    from ..fluid import Fluid, TaylorHood, solve_steady

    t0 = time.perf_counter()
    disk = Polygon.regular(run.n_sides, FAXEN["a"], center=(0.0, 0.0)).vertices
    if run.kind == "graded":
        mesh = meshing.graded_mesh(FAXEN["box"], [disk], sigma=run.sigma)
    else:
        mesh = meshing.uniform_mesh(FAXEN["box"], [disk], h=run.h)
    if run.seed:
        mesh = renumbered(mesh, run.seed)
    t1 = time.perf_counter()
    space = TaylorHood(mesh)
    t2 = time.perf_counter()
    flow = solve_steady(space, Fluid(1.0, 1.0), {"wall": (0, 0), "particle0": (1.0, 0.0)})
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
    from ..coupled.build import build_mesh
    from ..dem import DEMSystem
    from ..scene import MeshSpec, Scene, TimeSpec
    from ..simulation import Simulation

    scene = Scene.from_toml(SCENE)
    t_end = run.t_end or scene.time.t_end
    scene = replace(scene, output_dir=None, mesh=MeshSpec(run.kind, run.delta_l, run.sigma, run.h),
                    time=TimeSpec(t_end=t_end, dt=run.dt))
    # the mesh is built here, around the cores where the simulation's DEM puts them,
    # so that it can be renumbered (the particle moves < 1 % of an outline edge in 1 ms,
    # so no remesh undoes the renumbering)
    cores = DEMSystem.in_box([p.to_dem() for p in scene.particles], scene.domain,
                             scene.wall_thickness, law=scene.contact_law).core_outlines()
    t0 = time.perf_counter()
    meshed = build_mesh(scene, cores)
    if run.seed:
        meshed = renumbered(meshed, run.seed)
    t_mesh = time.perf_counter() - t0
    sim = Simulation(scene, output_dir=None, mesh=meshed)
    res = sim.run(progress=False)
    s, h = res.summary, res.history
    # the initial meshing is counted in the meshing phase, as when the simulation builds it
    ph = dict(s["wall_time"], meshing=s["wall_time"].get("meshing", 0.0) + t_mesh)
    wt = {k: ph.get(k, 0.0) for k in ("meshing", "assembly", "total")}
    wt["solve"] = ph.get("factorization", 0.0) + ph.get("solve", 0.0)
    wt["other"] = wt["total"] - wt["meshing"] - wt["assembly"] - wt["solve"]
    cx = 0.5 * (scene.domain[0] + scene.domain[2])
    return {"vertices": s["mesh"]["vertices"], "p2_nodes": s["mesh"]["p2_nodes"],
            "dofs": s["mesh"]["dofs"], "wall": wt, "wall_phases": ph,
            "quantity": "v_y(t_end) [m/s]", "value": float(h.vy[-1, 0]),
            "t": h.t.tolist(), "vy": h.vy[:, 0].tolist(),
            "cross": float(np.abs(h.vx[:, 0]).max() / np.abs(h.vy[:, 0]).max()),
            "x_drift": float(h.x[-1, 0] - scene.particles[0].polygon.vertices[0].mean()),
            "mirror_symmetric": mirror_symmetric(sim.mesh, 0, cx), "t_end": t_end}
