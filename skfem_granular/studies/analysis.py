"""The numbers of a study from its records: table rows (:func:`analyse`) with errors
against the reference and the rounding measures, fitted orders and the sweet spot."""

from __future__ import annotations

from dataclasses import asdict
from typing import Any

import numpy as np

from .definitions import COLUMNS, FAXEN, faxen_drag


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
        row: dict[str, Any] = {c: None for c in COLUMNS}
        row.update({k: v for k, v in asdict(r).items() if k in COLUMNS})
        row.update(key=r.key, vertices=rec["vertices"], p2_nodes=rec["p2_nodes"], dofs=rec["dofs"],
                   wall_time=rec["wall"]["total"], peak_rss_mb=rec["peak_rss_mb"],
                   quantity=rec["quantity"], value=rec["value"],
                   mirror_symmetric=rec["mirror_symmetric"])
        for ph in ("meshing", "assembly", "solve", "other"):
            row[f"wall_{ph}"] = rec["wall"].get(ph, 0.0)
        row["wall_warmup"] = rec.get("warmup", float("nan"))  # the process's, apart
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


def fit_order(x, err) -> float:
    """Slope ``p`` of ``err ~ x^-p`` (least squares in log-log; NaN with < 2 points)."""
    x, err = np.asarray(x, float), np.asarray(err, float)
    ok = np.isfinite(err) & (err > 0) & np.isfinite(x) & (x > 0)
    if ok.sum() < 2:
        return float("nan")
    return float(-np.polyfit(np.log(x[ok]), np.log(err[ok]), 1)[0])


def orders(rows) -> dict:
    """Per family: order in DOFs, written h-equivalent (``err ~ DOFs^(-p/2)``), unpermuted runs."""
    out = {}
    for fam in ("uniform", "graded", "sigma"):
        for sig in sorted({r["sigma"] or 0 for r in rows if r["family"] == fam}):
            sel = [
                r for r in rows if r["family"] == fam and not r["seed"] and (r["sigma"] or 0) == sig
            ]
            name = fam if fam != "sigma" else f"graded sigma={sig:g}"
            if len(sel) > 1:
                out[name] = 2 * fit_order([r["dofs"] for r in sel], [r["error"] for r in sel])
    return out


def pareto_front(points):
    """Indices of the non-dominated points (cost, error), sorted by cost."""
    idx = sorted(range(len(points)), key=lambda i: points[i])
    front, best = [], np.inf
    for i in idx:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def sweet_spot(rows, family="graded"):
    """Fits ``disc = A N^-a`` (``family``) and ``round = B N^b`` (renumbering spreads).

    Returns ``(N*, (A, a), (B, b))``: ``N*`` the DOFs where the fitted lines
    cross (beyond it refining cannot reduce the error), None without a crossing.
    """
    d = [
        r
        for r in rows
        if r["family"] == family
        and not r["seed"]
        and r["error"]
        and np.isfinite(r["error"])
        and r["error"] > 0
    ]
    q = [
        r
        for r in rows
        if r["rounding_renumber"]
        and np.isfinite(r["rounding_renumber"])
        and r["rounding_renumber"] > 0
    ]
    if len(d) < 2 or len(q) < 2:
        return None, None, None
    a = fit_order([r["dofs"] for r in d], [r["error"] for r in d])
    A = np.exp(np.mean([np.log(r["error"]) + a * np.log(r["dofs"]) for r in d]))
    b = -fit_order([r["dofs"] for r in q], [r["rounding_renumber"] for r in q])
    B = np.exp(np.mean([np.log(r["rounding_renumber"]) - b * np.log(r["dofs"]) for r in q]))
    n_star = float((A / B) ** (1 / (a + b))) if a + b > 0 and A > B else None
    return n_star, (float(A), float(a)), (float(B), float(b))
