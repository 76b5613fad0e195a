"""Figures of the collapse page from the benchmarks' results.

Usage: ``python benchmarks/collapse_figures.py --dry results/collapse_dry_*.json
[--flow-dir DIR --packing FILE.npz] [--out docs/figures]``.

- ``collapse_dry_runout.png``: ``(L - L0) / L0`` against ``t / tau_c`` of every dry run;
- ``collapse_dry_law.png``: final run-out against ``a`` (mean and sample standard deviation
  over the seeds) with the published dry laws;
- ``collapse_pressure_lines.png`` (with ``--flow-dir``): excess pore pressure along the
  base and 10 d_mean above it in the saved flow frames of an immersed run, over
  ``(rho_p - rho_f) g H0``;
- ``collapse_matrix_runout.png`` (with ``--matrix results/collapse_matrix_n200.json``): the
  run-out curves of the loose/dense, dry/immersed runs (immersed: the smallest core ratio);
- ``collapse_core_ratio_runout.png`` (with ``--matrix``): the immersed runs at every core
  ratio, colour by packing, line style by core ratio;
- ``collapse_matrix_pressure.png`` (with ``--matrix`` and ``--matrix-dir
  out/collapse_matrix_n200``): excess pore pressure along the base under the loose and
  the dense immersed columns (the first seed) in their first saved frames after the
  release.

``--stem NAME`` names the matrix figures ``NAME_runout.png`` and ``NAME_pressure.png``
(default ``collapse_matrix``: another matrix, such as the 1000-grain runs, keeps its own);
the core-ratio figure is drawn when the matrix has immersed runs at two core ratios or more.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import meshio
import numpy as np

from skfem_granular.collapse import excess_pressure, line_points, reference_point
from skfem_granular.collapse.plots import (
    plot_pressure_lines,
    plot_runout_curves,
    plot_runout_law,
)
from skfem_granular.io import read_pvd
from skfem_granular.packing import load_packing

ROOT = Path(__file__).resolve().parents[1]


def dry_figures(paths, out):
    runs = [r for p in paths for r in json.loads(Path(p).read_text())["runs"]]
    curves = {f"a = {r['aspect']:.2f}, seed {r['seed']}": (r["runout_curve"]["t_over_tau"],
                                                            r["runout_curve"]["runout"])
              for r in runs}
    plot_runout_curves(curves, out / "collapse_dry_runout.png")
    aspects = sorted({r["aspect_wanted"] for r in runs})
    a = [np.mean([r["aspect"] for r in runs if r["aspect_wanted"] == x]) for x in aspects]
    m = [np.mean([r["runout"] for r in runs if r["aspect_wanted"] == x]) for x in aspects]
    s = [np.std([r["runout"] for r in runs if r["aspect_wanted"] == x], ddof=1)
         if sum(r["aspect_wanted"] == x for r in runs) > 1 else 0.0 for x in aspects]
    plot_runout_law(a, m, s, out / "collapse_dry_law.png",
                    label=f"this DEM ({runs[0]['n']} near-disks, mean and sd over seeds)")


def pressure_figure(flow_dir, packing_path, out):
    packing = load_packing(packing_path)
    flow_dir = Path(flow_dir)
    frames = read_pvd(flow_dir / "flow.pvd")
    X = meshio.read(frames[0][1]).points
    box = (X[:, 0].min(), X[:, 1].min(), X[:, 0].max(), X[:, 1].max())  # the tank
    ref = reference_point(box, packing.d_max)
    x0, x1 = 0.5 * packing.d_max, box[2] - 0.5 * packing.d_max
    scale = (packing.density - 1000.0) * 9.81 * packing.height
    lines, styles = {}, {}
    picked = [frames[1], frames[len(frames) // 2], frames[-1]]
    for k, (t, f) in enumerate(picked):
        for name, y, ls in (("base", 0.02 * packing.d_mean, "-"),
                            ("10 d", 10 * packing.d_mean, "--")):
            P = line_points(x0, x1, y)
            label = f"{name}, t = {1e3 * t:.1f} ms"
            lines[label] = excess_pressure(f, P, ref) / scale
            styles[label] = f"C{k}{ls}"
    plot_pressure_lines(P[0], lines, out / "collapse_pressure_lines.png", scale=packing.width,
                        ylabel=r"$(p - p_{ref}) / ((\rho_p - \rho_f) g H_0)$", styles=styles)


def matrix_figures(path, out, runs_dir=None, stem="collapse_matrix"):
    runs = json.loads(Path(path).read_text())["runs"]
    immersed = sorted({r["core_ratio"] for r in runs if r["medium"] == "immersed"})
    curves = {f"{r['state']}, {r['medium']}"
              + (f" (core {r['core_ratio']:g})" if r["medium"] == "immersed" else "")
              + f", seed {r['seed']}": (r["series"]["t_over_tau"], r["series"]["runout"])
              for r in sorted(runs, key=lambda r: r["run"])
              if r["medium"] == "dry" or r["core_ratio"] == immersed[0]}
    plot_runout_curves(curves, out / f"{stem}_runout.png")
    curves, styles = {}, {}
    for r in sorted(runs, key=lambda r: r["run"]):
        if r["medium"] == "immersed":
            label = f"{r['state']}, core {r['core_ratio']:g}, seed {r['seed']}"
            curves[label] = (r["series"]["t_over_tau"], r["series"]["runout"])
            styles[label] = ("C0" if r["state"] == "dense" else "C1") + (
                "-" if r["core_ratio"] == immersed[-1] else ":")
    if len(immersed) > 1:  # the core ratios side by side
        plot_runout_curves(curves, out / "collapse_core_ratio_runout.png", styles=styles)
    if runs_dir is None:
        return
    lines, styles = {}, {}
    first = min(r["seed"] for r in runs)  # one realisation per column: readable lines
    for k, r in enumerate(r for r in sorted(runs, key=lambda r: r["run"])
                          if r["medium"] == "immersed" and r["seed"] == first):
        folder = Path(runs_dir) / r["run"]
        packing = load_packing(ROOT / "benchmarks/results/packings"
                               / f"{r['state']}_a0.8_n{r['grains']}_seed{r['seed']}.npz")
        frames = read_pvd(folder / "flow.pvd")
        X = meshio.read(frames[0][1]).points
        box = (X[:, 0].min(), X[:, 1].min(), X[:, 0].max(), X[:, 1].max())
        ref = reference_point(box, packing.d_max)
        scale = (packing.density - 1000.0) * 9.81 * packing.height
        P = line_points(0.5 * packing.d_max, box[2] - 0.5 * packing.d_max,
                        0.02 * packing.d_mean)
        for j, (t, f) in enumerate(frames[1:3]):
            label = f"{r['state']} (core {r['core_ratio']:g}), t = {t / r['tau_c']:.2f} tau_c"
            lines[label] = excess_pressure(f, P, ref) / scale
            styles[label] = f"C{k}{'-' if j == 0 else '--'}"
    plot_pressure_lines(P[0], lines, out / f"{stem}_pressure.png", scale=packing.width,
                        ylabel=r"base: $(p - p_{ref}) / ((\rho_p - \rho_f) g H_0)$",
                        styles=styles)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dry", nargs="*", default=[])
    ap.add_argument("--flow-dir")
    ap.add_argument("--packing")
    ap.add_argument("--matrix", help="results/collapse_matrix_<tag>.json")
    ap.add_argument("--matrix-dir", help="the matrix runs' folders (for the pressure)")
    ap.add_argument("--stem", default="collapse_matrix", help="file names of the matrix figures")
    ap.add_argument("--out", default=str(ROOT / "docs" / "figures"))
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    if a.dry:
        dry_figures(a.dry, out)
    if a.flow_dir:
        pressure_figure(a.flow_dir, a.packing, out)
    if a.matrix:
        matrix_figures(a.matrix, out, a.matrix_dir, a.stem)


if __name__ == "__main__":
    main()
