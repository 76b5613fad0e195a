"""Figures of collapses (matplotlib, Agg): run-out curves and law, pressure lines."""

from __future__ import annotations

import numpy as np

from ..io import save_figure
from .laws import DRY_LAWS, dry_runout

__all__ = ["plot_pressure_lines", "plot_runout_curves", "plot_runout_law"]


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_runout_curves(curves, path=None, ax=None, styles=None):
    """``(L - L0) / L0`` against ``t / tau_c``; ``curves`` maps a label to ``(t/tau, runout)``
    (``styles``: label -> matplotlib format string)."""
    plt = _plt()
    fig = None
    if ax is None:
        fig, ax = plt.subplots(figsize=(5.5, 3.8))
    for label, (t, r) in curves.items():
        ax.plot(t, r, (styles or {}).get(label, "-"), label=label)
    ax.set_xlabel(r"$t / \tau_c$, $\tau_c = \sqrt{H_0/g}$")
    ax.set_ylabel(r"$(L - L_0) / L_0$")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    if fig is not None and path is not None:
        fig.tight_layout()
        try:
            save_figure(fig, path, dpi=120)
        finally:
            plt.close(fig)
    return ax


def plot_runout_law(aspect, runout, spread=None, path=None, label="this DEM"):
    """Final run-out against aspect ratio (mean, error bars ``spread``) with the dry laws."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(5.5, 3.8))
    a = np.geomspace(0.3, 6.0, 100)
    for name in DRY_LAWS:
        ax.plot(a, dry_runout(a, name), "--", label=name)
    ax.errorbar(aspect, runout, yerr=spread, fmt="o", color="k", capsize=3, label=label)
    ax.set_xscale("log")
    ax.set_yscale("log")
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    for axis in (ax.xaxis, ax.yaxis):
        axis.set_major_formatter(ScalarFormatter())
        axis.set_minor_formatter(NullFormatter())
    ax.set_xticks([0.3, 0.5, 1, 2, 4, 6])
    ax.set_yticks([0.5, 1, 2, 4, 8])
    ax.set_xlabel(r"$a = H_0 / L_0$")
    ax.set_ylabel(r"$(L_\infty - L_0) / L_0$")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    if path is not None:
        try:
            save_figure(fig, path, dpi=120)
        finally:
            plt.close(fig)
    return fig


def plot_pressure_lines(x, lines, path=None, scale=1.0, ylabel="excess pore pressure (Pa)",
                        styles=None):
    """Excess pore pressure along horizontal lines; ``lines`` maps a label to ``(n,)`` values
    (``styles``: label -> matplotlib format string)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(5.5, 3.5))
    for label, p in lines.items():
        ax.plot(np.asarray(x) / scale, p, (styles or {}).get(label, "-"), label=label)
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.set_xlabel("x / L0" if scale != 1.0 else "x (m)")
    ax.set_ylabel(ylabel)
    ax.legend(fontsize=8)
    fig.tight_layout()
    if path is not None:
        try:
            save_figure(fig, path, dpi=120)
        finally:
            plt.close(fig)
    return fig
