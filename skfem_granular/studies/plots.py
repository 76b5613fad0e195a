"""Figures of a study (matplotlib, Agg): Pareto front, convergence, the paper's Fig. 2."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io import save_figure
from .analysis import orders, pareto_front, sweet_spot

STYLE = {"uniform": ("o", "C0"), "graded": ("s", "C1"), "sigma": ("^", "C2"), "dt": ("D", "C3")}


def require_matplotlib() -> None:
    """Raise ImportError, naming the package and the extra to install, unless matplotlib
    imports: the figures come after every run, so a study checks this before the first."""
    try:
        import matplotlib  # noqa: F401
    except ImportError as exc:
        raise ImportError(f"the study's figures need matplotlib ({exc}); install it with "
                          "pip install 'skfem-granular[plot]'") from exc


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _label(fam, sigma=None):
    if fam == "sigma":
        return f"graded, sigma = {sigma:g}"
    return {"graded": "graded (Eq. 4 sigma)", "uniform": "uniform", "dt": "graded, time step"}[fam]


def _groups(rows):
    """Unpermuted rows with a finite positive error, grouped by (family, sigma)."""
    out = {}
    for r in rows:
        e = r["error"]
        if r["seed"] or e is None or not np.isfinite(e) or e <= 0:
            continue
        out.setdefault((r["family"], r["sigma"]), []).append(r)
    return out


def _finish(plt, fig, ax, path, xlabel, title, fontsize=8) -> Path:
    """Labels, grid and legend of an error plot; save to ``path`` and close."""
    ax.set_xlabel(xlabel)
    ax.set_ylabel("relative error")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=fontsize)
    fig.tight_layout()
    try:
        return save_figure(fig, path, dpi=120)
    finally:
        plt.close(fig)


def plot_pareto(rows, path, title=""):
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    allp = []
    for (fam, sig), sel in sorted(_groups(rows).items(), key=lambda kv: str(kv[0])):
        m, c = STYLE[fam]
        if fam == "sigma":
            c = "C2" if sig < 1.3 else "C4"
        x = [r["wall_time"] for r in sel]
        y = [r["error"] for r in sel]
        if fam == "dt":
            # time-step errors are measured against the smallest step on the same mesh:
            # a different reference, so they are shown hollow and kept off the front
            ax.loglog(x, y, m, color=c, mfc="none", alpha=0.85,
                      label=f"{_label(fam, sig)} (vs smallest dt, same mesh; not on the front)")
            continue
        ax.loglog(x, y, m, color=c, label=_label(fam, sig), alpha=0.85)
        allp += list(zip(x, y, strict=True))
    if allp:
        f = [allp[i] for i in pareto_front(allp)]
        ax.step(
            [p[0] for p in f], [p[1] for p in f], "k--", where="post", lw=1, label="Pareto front"
        )
    return _finish(
        plt, fig, ax, path, "wall time per run [s]", title or "error against cost", fontsize=8
    )


def plot_convergence(rows, path, title=""):
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    ords = orders(rows)
    for (fam, sig), sel in sorted(_groups(rows).items(), key=lambda kv: str(kv[0])):
        if fam == "dt":
            continue
        m, c = STYLE[fam]
        if fam == "sigma":
            c = "C2" if sig < 1.3 else "C4"
        sel = sorted(sel, key=lambda r: r["dofs"])
        x = np.array([r["dofs"] for r in sel], float)
        y = np.array([r["error"] for r in sel], float)
        name = fam if fam != "sigma" else f"graded sigma={sig:g}"
        p = ords.get(name, np.nan)
        ax.loglog(x, y, m, color=c, label=f"{_label(fam, sig)}: order {p:.2f}")
        if len(x) > 1:
            cst = np.exp(np.mean(np.log(y) + p / 2 * np.log(x)))
            ax.loglog(x, cst * x ** (-p / 2), "-", color=c, lw=1)
    return _finish(
        plt,
        fig,
        ax,
        path,
        "DOFs",
        title or "convergence (orders h-equivalent: err ~ DOFs^(-p/2))",
        fontsize=8,
    )


def _fig2_discretisation(ax, rows):
    """Discretisation error against DOFs, one line per mesh family."""
    for fam in ("uniform", "graded"):
        sel = sorted((r for r in rows if r["family"] == fam and not r["seed"] and r["error"]
                      and np.isfinite(r["error"]) and r["error"] > 0),
                     key=lambda r: r["dofs"])
        m, c = STYLE[fam]
        ax.loglog([r["dofs"] for r in sel], [r["error"] for r in sel], m + "-", color=c,
                  label=f"discretisation error, {_label(fam)}")


def _fig2_rounding(ax, rows):
    """The rounding-error measures against DOFs (exact zeros drawn at 1e-17)."""
    for col, m, lab in (
        ("rounding_renumber", "x", "rounding: spread over node renumberings"),
        ("rounding_field", "1", "rounding: renumbering spread, pressure field"),
        ("rounding_mirror", "+", "rounding: cross-stream/stream, mirror mesh"),
    ):
        sel = [r for r in rows if not r["seed"] and r.get(col) is not None and np.isfinite(r[col])]
        if not sel:
            continue
        pos = [r for r in sel if r[col] > 0]
        color = {"rounding_renumber": "k", "rounding_field": "C5"}.get(col, "C3")
        ax.loglog([r["dofs"] for r in pos], [r[col] for r in pos], m, ms=8, color=color, label=lab)
        zero = [r for r in sel if r[col] == 0]
        if zero:
            ax.loglog([r["dofs"] for r in zero], [1e-17] * len(zero), m, ms=8, color="0.5",
                      label=f"{lab.split(':')[1].strip()} = 0 exactly (drawn at 1e-17)")


def _fig2_fits(ax, rows):
    """The two fitted power laws and where they cross (the sweet spot)."""
    n_star, disc, rnd = sweet_spot(rows)
    if not (disc and rnd):
        return
    dofs = [r["dofs"] for r in rows]
    lo, hi = min(dofs), max(dofs)
    x = np.geomspace(lo, max(hi, n_star or hi) * 1.5, 100)
    ax.loglog(x, disc[0] * x ** -disc[1], ":", color="C1", lw=1)
    ax.loglog(x, rnd[0] * x ** rnd[1], ":", color="k", lw=1,
              label=f"fits: disc ~ N^-{disc[1]:.2f}, rounding ~ N^{rnd[1]:.2f}")
    if n_star:
        extra = " (extrapolated)" if n_star > hi else ""
        ax.axvline(n_star, color="C2", lw=2, alpha=0.6,
                   label=f"sweet spot (fits cross) N = {n_star:.2g} DOFs{extra}")


def plot_fig2(rows, path, title=""):
    """The paper's Fig. 2, measured: discretisation error falls, rounding error grows."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    _fig2_discretisation(ax, rows)
    _fig2_rounding(ax, rows)
    _fig2_fits(ax, rows)
    return _finish(plt, fig, ax, path, "DOFs",
                   title or "discretisation vs rounding error (paper Fig. 2, measured)",
                   fontsize=7)


def all_plots(rows, out_dir, study):
    """``pareto.png``, ``convergence.png`` and ``fig2.png`` in ``out_dir``."""
    out_dir = Path(out_dir)
    q = "v_y(t_end)" if study == "single-particle" else "Faxen drag"
    return [
        plot_pareto(rows, out_dir / "pareto.png", f"{study}: {q} error against wall time"),
        plot_convergence(rows, out_dir / "convergence.png", f"{study}: {q} error against DOFs"),
        plot_fig2(
            rows,
            out_dir / "fig2.png",
            f"{study}: discretisation vs rounding (paper Fig. 2, measured)",
        ),
    ]
