"""Figures of the settling study (:mod:`.settling`): Pareto fronts and convergence per axis."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io import save_figure
from .settling import QUANTITIES, front

MARKERS = {"base": "*", "delta_l": "o", "sigma": "^", "dt": "D", "remesh": "s"}
COLORS = {"ale": "C0", "fixed": "C3"}
LABELS = {"re_max": "max Re_p", "t_fall": "settling time t_fall"}
AXES = {"delta_l": ("outline piece length delta_l [m]", False),
        "sigma": ("grading sigma", False),
        "dt": ("time step [s] (error against the smallest step, same mesh)", False),
        "remesh": ("remesh threshold (ALE: radii travelled; fixed: fraction of an edge)", True)}


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _ok(r, q, pre=""):
    e = r.get(f"error_{pre}{q}")
    return e is not None and np.isfinite(e) and e > 0


def plot_pareto(rows, path) -> Path:
    """Error against wall time, one panel per quantity; the front over mesh/remesh/motion."""
    plt = _plt()
    fig, axs = plt.subplots(1, 2, figsize=(11, 4.4))
    for ax, q in zip(axs, QUANTITIES, strict=True):
        seen = set()
        for r in rows:
            if not _ok(r, q):
                continue
            lab = f"{r['family']}, {r['motion']}"
            hollow = r["family"] == "dt"
            ax.loglog(r["wall"], r[f"error_{q}"], MARKERS[r["family"]], color=COLORS[r["motion"]],
                      mfc="none" if hollow else COLORS[r["motion"]], ms=7,
                      label=None if lab in seen else lab + (" (vs smallest dt)" if hollow else ""))
            seen.add(lab)
        f = front(rows, q)
        if f:
            ax.step([r["wall"] for r in f], [r[f"error_{q}"] for r in f], "k--", where="post",
                    lw=1, label="Pareto front")
        ax.set_xlabel("wall time per run [s]")
        ax.set_ylabel("relative error")
        ax.set_title(f"{LABELS[q]}: error against cost")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6)
    fig.tight_layout()
    try:
        return save_figure(fig, path, dpi=110)
    finally:
        plt.close(fig)


def plot_convergence(rows, path) -> Path:
    """Error against each axis' parameter (both quantities, both motions)."""
    plt = _plt()
    fig, axs = plt.subplots(2, 2, figsize=(11, 8))
    for ax, (axis, (xlabel, logx)) in zip(axs.ravel(), AXES.items(), strict=True):
        for motion in ("ale", "fixed"):
            sel = [r for r in rows if r["motion"] == motion and r["family"] in (axis, "base")]
            pre = "dt_" if axis == "dt" else ""  # the step-only error on the dt axis
            for q, ls in zip(QUANTITIES, ("-", ":"), strict=True):
                pts = [(r["axes"][axis], r[f"error_{pre}{q}"]) for r in sel if _ok(r, q, pre)]
                if pts:
                    pts.sort()
                    ax.plot(*zip(*pts, strict=True), MARKERS.get(axis, "o") + ls,
                            color=COLORS[motion], mfc="none" if q == "t_fall" else None,
                            label=f"{LABELS[q]}, {motion}")
        ax.set_yscale("log")
        if logx:
            ax.set_xscale("log")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("relative error")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6)
    fig.suptitle("settling disk (check 2): error per axis, the others at the base")
    fig.tight_layout()
    try:
        return save_figure(fig, path, dpi=110)
    finally:
        plt.close(fig)
