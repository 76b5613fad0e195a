"""Benchmark report: where the long runs of a collapse matrix stand, read from their files.

The 1000-grain immersed collapses run over many sittings (``collapse_matrix.py --to-rest
--checkpoint-every 25`` continues a stopped run). This script reads the ``history.csv`` of
every run folder under ``ROOT`` as it is (finished or not; a last row still being written
is left out) and writes, per run, how far it has come and its series so far (run-out,
horizontal and vertical kinetic energy, front Froude number against ``t / tau_c``,
:func:`skfem_granular.collapse.collapse_series`), plus a figure of the run-out curves:
runs still going drawn solid up to where they are, finished runs of ``--matrix`` (the
dry ones) dashed. For immersed runs it also reads the excess pore pressure along the base
(0.02 d_mean above the floor, :func:`skfem_granular.collapse.excess_pressure` relative to
the still fluid at the tank's top right corner, over ``(rho_p - rho_f) g H0``) in every
flow frame saved after the release, with its mean over the column's foot (``d_max / 2``
to ``L0 - d_max / 2``; points inside grain cores left out), and draws those lines
(``--pressure-figure``), and renders the last saved frame of each immersed run with the
pressure coloured (``--snapshot-figure``; pyvista, off-screen).

Usage::

    python benchmarks/collapse_progress.py out/collapse_matrix_n1000 --n 1000 \\
        --matrix benchmarks/results/collapse_matrix_n1000.json \\
        --out benchmarks/results/collapse_progress_n1000.json \\
        --figure docs/figures/collapse_n1000_immersed_progress.png \\
        --pressure-figure docs/figures/collapse_n1000_immersed_pressure.png \\
        --snapshot-figure docs/figures/collapse_n1000_immersed_snapshots.png
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from collapse_matrix import packing  # noqa: E402

RUN_NAME = re.compile(r"^(?P<state>dense|loose)_(?P<medium>dry|immersed)"
                      r"(?:_core(?P<core>[0-9.]+))?_s(?P<seed>\d+)$")


def complete_rows(path: Path, dest: Path) -> int:
    """Copy ``path`` to ``dest`` without a last line that is still being written; the
    number of data rows copied."""
    raw = path.read_bytes()
    end = raw.rfind(b"\n")
    raw = raw[: end + 1] if end >= 0 else b""
    dest.write_bytes(raw)
    return max(raw.count(b"\n") - 1, 0)


def progress(folder: Path, n: int, every: int) -> dict | None:
    """How far the run in ``folder`` has come and its series so far (None: no rows yet)."""
    from skfem_granular.collapse import (
        collapse_series,
        column_scene,
        history_columns,
        time_scale,
    )

    m = RUN_NAME.match(folder.name)
    if m is None or not (folder / "history.csv").exists():
        return None
    pk = packing(n, m["state"], int(m["seed"]))
    with tempfile.TemporaryDirectory(prefix="collapse_progress_") as tmp:
        copy = Path(tmp) / "history.csv"
        if complete_rows(folder / "history.csv", copy) == 0:
            return None
        cols = history_columns(copy)
    rows = np.unique(np.r_[np.arange(0, cols["t"].size, every), cols["t"].size - 1])
    cols = {k: v[rows] for k, v in cols.items()}
    immersed = m["medium"] == "immersed"
    domain = column_scene(pk, fluid=immersed,
                          core_ratio=float(m["core"]) if immersed else 0.8).domain
    s = collapse_series(cols, pk, domain)
    finished = (folder / "rest.json").exists() or (
        (folder / "summary.json").exists()
        and json.loads((folder / "summary.json").read_text()).get("status") == "completed")
    tau = time_scale(pk)
    return {"run": folder.name, "state": m["state"], "medium": m["medium"],
            "core_ratio": float(m["core"]) if m["core"] else None, "seed": int(m["seed"]),
            "finished": finished, "t_end": float(cols["t"][-1]),
            "t_end_over_tau": float(s["t_over_tau"][-1]), "tau_c": tau, "rows_every": every,
            "series": {k: np.asarray(s[k]).tolist()
                       for k in ("t_over_tau", "runout", "E_x", "E_y", "froude")},
            "pressure": base_pressure(folder, pk) if immersed else [],
            "so_far": so_far(folder)}


def so_far(folder: Path) -> dict:
    """What the run has cost and met so far: its counters (``summary.json``, as of the
    last checkpoint or stop) and its cost over every process (``cost.json``), with the
    poorest mesh its steps ended on since the library records it."""
    out: dict = {}
    if (folder / "summary.json").exists():
        s = json.loads((folder / "summary.json").read_text())
        out.update({k: s.get(k) for k in ("steps", "remeshes", "remesh_reasons", "retries",
                                          "factorizations", "jacobian_refreshes", "failed")})
    if (folder / "cost.json").exists():
        c = json.loads((folder / "cost.json").read_text())
        out.update({k: c.get(k) for k in ("cpu_s", "wall_s", "processes", "peak_mb",
                                          "mesh_min_angle", "mesh_min_area_ratio",
                                          "mesh_steps_checked")})
    return out


def base_pressure(folder: Path, pk) -> list:
    """Excess pore pressure along the base in the flow frames saved after the release."""
    import meshio

    from skfem_granular.collapse import excess_pressure, line_points, reference_point
    from skfem_granular.io import read_pvd

    if not (folder / "flow.pvd").exists():
        return []
    frames = [(t, f) for t, f in read_pvd(folder / "flow.pvd") if t > 0.0]
    if not frames:
        return []
    X = meshio.read(frames[0][1]).points
    box = (X[:, 0].min(), X[:, 1].min(), X[:, 0].max(), X[:, 1].max())  # the tank
    ref = reference_point(box, pk.d_max)
    scale = (pk.density - 1000.0) * 9.81 * pk.height
    P = line_points(0.5 * pk.d_max, box[2] - 0.5 * pk.d_max, 0.02 * pk.d_mean)
    foot = P[0] <= pk.width - 0.5 * pk.d_max
    out = []
    for t, f in frames:
        p = excess_pressure(f, P, ref) / scale
        out.append({"t": float(t), "frame": Path(f).name,
                    "foot_mean": float(np.nanmean(p[foot])),
                    "x_over_L0": (P[0] / pk.width).tolist(),
                    "base": [None if not np.isfinite(v) else float(v) for v in p]})
    return out


def pressure_figure(records: list, path: Path) -> None:
    """Base pressure lines of the immersed runs, colour by packing, style by frame."""
    from skfem_granular.collapse.plots import plot_pressure_lines

    lines, styles, x = {}, {}, None
    for r in records:
        frames = r.get("pressure", [])
        for k, fr in enumerate(frames):
            label = f"{r['state']}, t = {fr['t'] / r['tau_c']:.2f} tau_c"
            lines[label] = np.array([np.nan if v is None else v for v in fr["base"]])
            colour = "C0" if r["state"] == "dense" else "C3"
            styles[label] = colour + ("-", "--", ":", "-.")[k % 4]
            x = np.asarray(fr["x_over_L0"])
    if not lines:
        return
    fig = plot_pressure_lines(x, lines, ylabel=r"base: $(p - p_{ref}) / ((\rho_p - \rho_f) g H_0)$",
                              styles=styles)
    fig.axes[0].set_xlabel("x / L0")
    fig.axes[0].set_xlim(0.0, min(2.5, float(x.max())))  # the flow; the tank's far part is still
    fig.axes[0].legend(fontsize=6, ncol=2)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)


def snapshot_figure(root: Path, records: list, n: int, path: Path) -> None:
    """The last saved frame of every immersed run, the pressure coloured (pyvista,
    off-screen): the column's part of the tank, colours centred on the still fluid's
    pressure at the reference point, so that blue is suction and red overpressure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import meshio

    from skfem_granular.collapse import frame_pressure, reference_point
    from skfem_granular.io import read_pvd
    from skfem_granular.viz import render_frame

    pictures = []
    for r in (r for r in records if r["medium"] == "immersed"):
        folder = root / r["run"]
        t, flow_vtu = read_pvd(folder / "flow.pvd")[-1]
        particles = dict(read_pvd(folder / "particles.pvd")).get(t)
        pk = packing(n, r["state"], r["seed"])
        X = meshio.read(flow_vtu).points
        tank = (X[:, 0].min(), X[:, 1].min(), X[:, 0].max(), X[:, 1].max())
        p_ref = float(frame_pressure(flow_vtu, reference_point(tank, pk.d_max))[0])
        m = (pk.density - 1000.0) * 9.81 * pk.height * 0.3  # 0.3 of the immersed weight
        box = (tank[0], tank[1], tank[0] + 3.0 * pk.width, tank[1] + 1.25 * pk.height)
        pictures.append(render_frame(
            flow_vtu, particles, field="pressure", box=box, clim=(p_ref - m, p_ref + m),
            window_size=(1200, 520),
            title=(f"{r['state']}, t = {t:.3f} s ({t / r['tau_c']:.2f} tau_c): pressure (Pa), "
                   f"still fluid {p_ref:+.1f} Pa")))
    if not pictures:
        return
    fig, axes = plt.subplots(len(pictures), 1, figsize=(10, 4.4 * len(pictures)))
    for ax, pic in zip(np.atleast_1d(axes), pictures, strict=True):
        ax.imshow(pic.image)
        ax.set_axis_off()
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


def figure(records: list, matrix: list, path: Path) -> None:
    """Run-out curves: the runs read here solid, the finished runs of the matrix dashed."""
    from skfem_granular.collapse.plots import plot_runout_curves

    colour = {"dense": "C0", "loose": "C3"}
    curves, styles = {}, {}
    for r in matrix:
        label = f"{r['state']} {r['medium']}, seed {r['seed']} (to rest)"
        curves[label] = (r["series"]["t_over_tau"], r["series"]["runout"])
        styles[label] = "--"
    for r in records:
        where = "to rest" if r["finished"] else f"so far, {r['t_end_over_tau']:.1f} tau_c"
        label = f"{r['state']} {r['medium']}, seed {r['seed']} ({where})"
        curves[label] = (r["series"]["t_over_tau"], r["series"]["runout"])
        styles[label] = "-"
    ax = plot_runout_curves(curves, styles=styles)
    for line in ax.get_lines():
        state = line.get_label().split()[0]
        line.set_color(colour.get(state, "k"))
        if "immersed" not in line.get_label():
            line.set_alpha(0.5)
    ax.legend(fontsize=7)
    fig = ax.figure
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", type=Path, help="the matrix's run folders (out/collapse_matrix_<tag>)")
    ap.add_argument("--n", type=int, required=True, help="grains per column")
    ap.add_argument("--media", nargs="+", default=["immersed"], help="which runs to read")
    ap.add_argument("--every", type=int, default=5, help="read every k-th row of a history")
    ap.add_argument("--matrix", type=Path, help="results/collapse_matrix_<tag>.json: its "
                    "finished dry runs are drawn beside")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--figure", type=Path)
    ap.add_argument("--pressure-figure", type=Path)
    ap.add_argument("--snapshot-figure", type=Path,
                    help="the last saved frame of each immersed run, pressure coloured")
    args = ap.parse_args(argv)
    if not args.root.is_dir():
        sys.exit(f"root: {args.root} is not a folder")
    if args.every < 1:
        sys.exit(f"--every = {args.every}: must be at least 1")
    records = []
    for folder in sorted(p for p in args.root.iterdir() if p.is_dir()):
        m = RUN_NAME.match(folder.name)
        if m is None or m["medium"] not in args.media:
            continue
        rec = progress(folder, args.n, args.every)
        if rec is not None:
            records.append(rec)
            print(f"{rec['run']}: t = {rec['t_end']:.4f} s ({rec['t_end_over_tau']:.2f} tau_c), "
                  f"run-out {rec['series']['runout'][-1]:.3f}"
                  + (" (finished)" if rec["finished"] else ""), flush=True)
            for fr in rec["pressure"]:
                print(f"  {fr['frame']}: t = {fr['t']:.4f} s, base pressure over the foot "
                      f"{fr['foot_mean']:+.4f}", flush=True)
    matrix = []
    if args.matrix is not None:
        matrix = [r for r in json.loads(args.matrix.read_text())["runs"]
                  if r["medium"] == "dry" and "series" in r]
    args.out.write_text(json.dumps({"benchmark": "collapse_progress", "root": str(args.root),
                                    "grains": args.n, "runs": records}, indent=1) + "\n")
    if args.figure is not None:
        figure(records, matrix, args.figure)
    if args.pressure_figure is not None:
        pressure_figure(records, args.pressure_figure)
    if args.snapshot_figure is not None:
        snapshot_figure(args.root, records, args.n, args.snapshot_figure)


if __name__ == "__main__":
    main()
