"""Benchmark: what makes a moving mesh remesh, and whether a local repair would do.

A long run remeshes whenever its moved mesh has, or would have one step ahead, a
triangle below the ALE rule's bounds (smallest angle ``ALE_MIN_ANGLE``, area ratio
``ALE_MIN_AREA_RATIO``: :func:`skfem_granular.coupled.ale_rules.remesh_reason`). This
script resumes a copy of a run's checkpoint and history (the run itself is not touched), lets it
step, and at every remesh the rule asks for records, for the mesh it replaces:

- the triangles below the bounds now and at the poses extrapolated 1, 2 and 3 steps
  ahead (the rule's own extrapolation), with the smallest angle there;
- how many of those one edge flip would repair (the edge opposite the largest angle,
  both new triangles above the bound and the same orientation);
- how many remain after Laplacian smoothing of the interior vertices (those the mesh
  motion solves for in both directions) within 1, 2 or 3 rings of the bad triangles,
  1 or 3 sweeps.

It measures what a local repair could save; the library does not repair meshes.

Usage::

    python benchmarks/remesh_triggers.py out/collapse_matrix_n1000/loose_immersed_core0.9_s0 \\
        --steps 6 --out benchmarks/results/remesh_triggers_loose_n1000.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from run_copy import check_run, run_argument, scratch_copy

from meshing.quality import angles, signed_areas

AHEAD = (1, 2, 3)
RINGS = (1, 2, 3)
SWEEPS = (1, 3)


def bad_triangles(p, t, area_ref, min_angle: float, min_ratio: float) -> np.ndarray:
    """Indices of the triangles at ``p`` below the remesh rule's bounds."""
    small = angles(p, t).min(axis=0) < min_angle
    return np.flatnonzero(small | (signed_areas(p, t) / area_ref < min_ratio))


def flip_repairs(p, t, bad, min_angle: float) -> int:
    """How many of the ``bad`` triangles one flip of their longest edge repairs."""
    nv, nel = p.shape[1], t.shape[1]
    ends = np.sort(np.concatenate([t[[1, 2]], t[[2, 0]], t[[0, 1]]], axis=1), axis=0)
    key = ends[0].astype(np.int64) * nv + ends[1].astype(np.int64)  # edge opposite vertex k
    owner = np.tile(np.arange(nel), 3)
    order = np.argsort(key, kind="stable")
    ang = angles(p, t)
    repaired = 0
    for e in bad:
        j = int(np.argmax(ang[:, e]))
        a, b = int(t[(j + 1) % 3, e]), int(t[(j + 2) % 3, e])
        k = min(a, b) * nv + max(a, b)
        lo, hi = np.searchsorted(key[order], [k, k + 1])
        other = [owner[i] for i in order[lo:hi] if owner[i] != e]
        if not other:  # a boundary edge: no flip
            continue
        f = other[0]
        d = next(int(v) for v in t[:, f] if v not in (a, b))
        c = int(t[j, e])
        new = np.array([[c, a, d], [c, d, b]]).T
        same = np.sign(signed_areas(p, new)) == np.sign(signed_areas(p, t[:, [e]]))
        if np.all(same) and angles(p, new).min() >= min_angle:
            repaired += 1
    return repaired


def smoothing_repairs(p, t, bad, free, area_ref, bounds) -> dict:
    """Triangles left below the bounds after Laplacian smoothing near the ``bad`` ones."""
    nv = p.shape[1]
    edges = np.concatenate([t[[0, 1]], t[[1, 2]], t[[2, 0]]], axis=1)
    A = sp.csr_matrix((np.ones(2 * edges.shape[1]), (np.r_[edges[0], edges[1]],
                                                     np.r_[edges[1], edges[0]])), shape=(nv, nv))
    A.data[:] = 1.0
    degree = np.asarray(A.sum(axis=1)).ravel()
    out = {}
    for rings in RINGS:
        near = np.zeros(nv, dtype=bool)
        near[t[:, bad].ravel()] = True
        for _ in range(rings - 1):
            near |= (A @ near.astype(float)) > 0
        move = np.flatnonzero(near & free)
        for sweeps in SWEEPS:
            q = p.copy()
            for _ in range(sweeps):
                q[:, move] = ((A @ q.T).T / degree)[:, move]
            left = bad_triangles(q, t, area_ref, *bounds)
            out[f"rings{rings}_sweeps{sweeps}"] = {
                "moved_vertices": int(move.size), "left": int(left.size),
                "min_angle": float(angles(q, t).min())}
    return out


def survey(motion, q, q_prev, dt_ratio, bounds) -> dict:
    """The bad triangles of ``motion``'s mesh now and ahead, and what repairs them."""
    free = np.zeros((2, motion.p_ref.shape[1]), dtype=bool)
    free[0, motion.free[0]] = True
    free[1, motion.free[1]] = True
    free = free[0] & free[1]  # interior vertices (wall vertices slide along one axis only)
    rec = {}
    for k in AHEAD:
        p = motion.positions(q + k * (q - q_prev) * dt_ratio)
        bad = bad_triangles(p, motion.t, motion.area_ref, *bounds)
        rec[f"ahead{k}"] = {
            "bad": int(bad.size), "min_angle": float(angles(p, motion.t).min()),
            "one_flip_repairs": flip_repairs(p, motion.t, bad, bounds[0]),
            "smoothing": smoothing_repairs(p, motion.t, bad, free, motion.area_ref, bounds)}
    return rec


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    run_argument(ap)
    ap.add_argument("--steps", type=int, default=6)
    ap.add_argument("--out", type=Path, default=None, help="JSON file written")
    args = ap.parse_args(argv)
    check_run(args.run, steps=args.steps)
    import skfem_granular.coupled.mesh_keeper as keeper
    from skfem_granular.coupled import ale_rules
    from skfem_granular.simulation import Simulation

    bounds = (ale_rules.ALE_MIN_ANGLE, ale_rules.ALE_MIN_AREA_RATIO)
    rule = keeper.remesh_reason
    records: list[dict] = []

    def recorded(motion, state, moved, q, dt_ratio, *rest):
        reason = rule(motion, state, moved, q, dt_ratio, *rest)
        if reason is not None and dt_ratio is not None:
            records.append({"step": step[0] + 1, "reason": reason,
                            "triangles": int(motion.t.shape[1]),
                            **survey(motion, q, state.q_prev, dt_ratio, bounds)})
            print(json.dumps(records[-1]), flush=True)
        return reason

    keeper.remesh_reason = recorded  # the mesh keeper asks its module for the rule
    step = [0]
    with scratch_copy(args.run, "remesh_triggers_") as folder:
        # every remesh the rule asks for, as a remesh (a repair would ask the rule again)
        sim = Simulation.resume(folder, mesh_repair="none")
        for _ in sim.evolve():
            step[0] += 1
            if step[0] >= args.steps:
                break
    result = {"benchmark": "remesh_triggers", "run": args.run.name, "steps": step[0],
              "bounds": {"min_angle": bounds[0], "min_area_ratio": bounds[1]},
              "remeshes": records}
    if args.out is not None:
        args.out.write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
