"""Settling runs compared with published curves (digitised, as package data).

For every digitised curve ``skfem_granular/validation_data/curve_<name>.json``
(format: :mod:`skfem_granular.validation.curves`) this reads the run its
``setup.scene`` names from a results file of ``benchmarks/sedimentation.py``
(``setup.result``, default :data:`RESULTS_OF`) and compares:

- a settling curve (a column ``vy``): the L2 difference of the vertical velocity
  over the fall (from the start to the earlier of the two landings, speed below
  10 % of its maximum), the landing times and the time the centre reaches
  ``floor + 2 radii``, a gap of one radius
  (:func:`~skfem_granular.validation.curves.compare_settling`);
- any other column (``x1``, ``y2``, ``vy1``, ...: particle ``k``'s ``x``, ``y``,
  ``vy``, ``k`` from 1): the L2 difference over the common time interval.

Writes ``benchmarks/results/settling_curves.json`` and prints a markdown table.
With no curve shipped yet it says so and which file names it looks for.

Usage: ``python benchmarks/settling_curves.py [--results FILE.json]``
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import numpy as np

from skfem_granular.scene import Scene
from skfem_granular.validation import curves

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"

#: The results file of each scene's run (benchmarks/sedimentation.py), unless the
#: curve's ``setup.result`` names another.
RESULTS_OF = {"settling_disk_channel": "sedimentation_settling_base.json",
              "dkt_two_disks": "sedimentation_dkt_ale_5s.json"}


def run_column(history: dict, column: str) -> np.ndarray:
    """The run's values for a curve column: ``vy`` is particle 0's, ``vy2`` particle 1's."""
    m = re.fullmatch(r"([a-z]+)(\d*)", column)
    if m is None or m.group(1) not in history:
        raise ValueError(f"curve column {column!r}: no such history column "
                         f"({', '.join(history)})")
    a = np.asarray(history[m.group(1)], dtype=float)
    k = int(m.group(2)) - 1 if m.group(2) else 0
    return a if a.ndim == 1 else a[:, k]


def floor_height(scene_name: str) -> tuple[float, float]:
    """``(release height, centre height two radii above the floor)`` of a scene's disk
    (the core: the disk the fluid sees)."""
    scene = Scene.bundled(scene_name)
    p = scene.particles[0]
    V = np.asarray(p.polygon.vertices)
    radius = (p.core_ratio or 1.0) * float(np.hypot(*(V - V.mean(axis=1)[:, None])).max())
    return float(V[1].mean()), scene.domain[1] + 2.0 * radius


def compare(curve: curves.Curve, result: dict, t_max: float | None = None) -> dict:
    """Every column of ``curve`` against the run in ``result`` (a results file's dict);
    the non-settling columns over the common interval up to ``t_max`` (default: all)."""
    h = result["history"]
    t = np.asarray(h["t"], dtype=float)
    y0, y_stop = floor_height(result["scene"])
    out = {"curve": curve.name, "source": curve.source, "scene": result["scene"],
           "columns": {}}
    for col in curve.columns:
        if col == curve.x:
            continue
        if col == "vy":
            out["columns"][col] = curves.compare_settling(
                t, run_column(h, "y"), run_column(h, "vy"), curve, y_stop=y_stop, y0=y0)
            continue
        x_ref, y_ref = curve.series(col)
        d = curves.l2_difference(t, run_column(h, col), x_ref, y_ref,
                                 interval=None if t_max is None else (-np.inf, t_max))
        out["columns"][col] = {"l2": d.l2, "relative": d.relative, "max_abs": d.max_abs,
                               "interval": (d.x0, d.x1)}
        if col == "y":
            out["columns"][col]["t_floor"] = {
                "run": curves.time_to_floor(t, run_column(h, "y"), y_stop),
                "reference": curves.time_to_floor(x_ref, y_ref, y_stop)}
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--results", help="results file to compare (default: by scene)")
    ap.add_argument("--t-max", type=float, help="compare the curves up to this time (s)")
    ap.add_argument("--out", default="settling_curves.json",
                    help="file name in benchmarks/results")
    args = ap.parse_args()
    names = curves.available_curves()
    if not names:
        print("no digitised curves shipped yet: add skfem_granular/validation_data/"
              "curve_<name>.json (format: skfem_granular/validation/curves.py), e.g. "
              "curve_glowinski2001_settling_vy.json, curve_koblitz2017_settling_vy.json, "
              "curve_wan_turek2006_dkt.json")
        return
    rows = []
    for name in names:
        c = curves.load_curve(name)
        scene = c.setup.get("scene")
        file = args.results or c.setup.get("result") or RESULTS_OF.get(scene)
        if file is None:
            print(f"{name}: setup.scene = {scene!r} has no results file; pass --results")
            continue
        result = json.loads((RESULTS / Path(file).name).read_text())
        rows.append(compare(c, result, args.t_max))
    (RESULTS / args.out).write_text(json.dumps(rows, indent=1))
    print("| curve | column | L2 (rms) | relative | interval (s) | t_down run / ref | "
          "t_floor run / ref |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        for col, v in r["columns"].items():
            down = v.get("t_down", {})
            fl = v.get("t_floor", {})
            print(f"| {r['curve']} | {col} | {v['l2']:.4g} | {v['relative']:.4g} | "
                  f"{v['interval'][0]:.3g}-{v['interval'][1]:.3g} | "
                  f"{down.get('run', np.nan):.4g} / {down.get('reference', np.nan):.4g} | "
                  f"{fl.get('run', np.nan):.4g} / {fl.get('reference', np.nan):.4g} |")


if __name__ == "__main__":
    main()
