"""The summary of a run (``summary.json``): effects, mesh, steps, final state, wall times."""

from __future__ import annotations

import numpy as np

from ..io import History


def summarize(sim, hist: History) -> dict:
    """The summary of :class:`~skfem_granular.simulation.Simulation` ``sim`` with history ``hist``.

    ``status`` is ``"completed"``, ``"stopped"`` (by the signal named in
    ``stopped_by``; ``stopped_at_once`` when a second one ended the step),
    ``"failed"`` (the reason in ``failed``), ``"closed"`` (the caller broke off
    the loop) or ``"running"``.
    """
    sc = sim.scene
    ratios = sim.remesh_energy_ratios
    out = {
        "scene": sc.name,
        "effects": _effects(sim),
        "coupling": None if sc.dry else sc.coupling,
        "mesh_motion": None if sc.dry else ("ale" if sc.moving_mesh else "fixed"),
        "particles": sim.dem.n,
        "imposed_motion": [int(k) for k in np.flatnonzero(sim.dem.imposed)],
        "steps": len(hist),
        "t_end": float(hist.t[-1]) if len(hist) else 0.0,
        "dt": sc.time.dt,
        "remeshes": sim.remeshes,
        "remesh_reasons": None if sc.dry else dict(sim.stepper.remesh_reasons),
        "mesh_repairs": None if sc.dry else dict(sim.stepper.mesh_repairs),
        **({} if sc.dry else sim.stepper.factor_counts),
        "retries": sim.retries,
        "rejections": sim.rejections,
        "euler_steps_at_contacts": sim.euler_steps,
        "adaptive": sc.time.adaptive,
        "dt_range": ([float(hist.dt.min()), float(hist.dt.max())] if len(hist) else None),
        "remesh_energy_ratio_max": max(ratios, default=None),
        "status": sim.status,
        "stopped_by": sim.stopped_by,
        "stopped_at_once": sim.stopped_at_once,
        "failed": sim.failure,
        "warnings": list(sim.warnings),
        "wall_time": {k: round(v, 6) for k, v in sim.timings.items()},
    }
    if not sc.dry:
        out["mesh"] = _mesh(sim)
    if len(hist):  # the last row (always in memory)
        last = hist.rows[-1]
        out["final"] = {c: np.asarray(last[c], dtype=float).tolist()
                        for c in ("x", "y", "vx", "vy", "omega")}
    return out


def _effects(sim) -> dict:
    """The effects the run simulated (what its scene asked for, ``"auto"`` decided)."""
    sc, eff = sim.scene, sim.scene.effects
    return {"fluid": not sc.dry, "gravity": eff.gravity,
            "convection": (not sc.dry) and eff.convection, "contacts": sim.contacts_active,
            "rotation": eff.rotation, "remeshing": (not sc.dry) and eff.remeshing}


def _mesh(sim) -> dict:
    """The mesh in use: kind, sizes, quality (and the worst quality over the steps)."""
    import meshing

    st = meshing.mesh_stats(sim.mesh)
    out = {
        "kind": getattr(getattr(sim.stepper.meshed, "recipe", None), "kind",
                        sim.scene.mesh.kind),  # what "auto" chose
        "vertices": st.n_vertices,
        "p2_nodes": st.n_p2_nodes,
        "triangles": st.n_triangles,
        "dofs": int(sim.space.N),
        "min_angle": float(st.min_angle),
    }
    w = sim.stepper.worst_mesh  # the steps of this process (a resumed run: since then)
    out.update({
        "steps_checked": w["steps"],
        "min_angle_over_steps": float(w["min_angle"]) if w["steps"] else None,
        "min_area_ratio_over_steps": float(w["min_area_ratio"]) if w["steps"] else None,
    })
    return out
