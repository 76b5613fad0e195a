"""Fits, tables, figure and self-check of the scaling benchmark (:mod:`scaling`).

Everything here reads the results records of ``benchmarks/scaling.py``; nothing runs a
simulation. ``python benchmarks/scaling.py --refit`` redoes these from a results file.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: The fields every run record has (checked by :func:`check`).
RUN_KEYS = ("n", "grains", "t_end", "steps", "warmup_steps", "vertices_initial",
            "vertices_final", "dofs_initial", "dofs_final", "dofs_max", "remeshes",
            "remesh_reasons", "factorizations", "jacobian_refreshes", "retries",
            "euler_steps_at_contacts", "max_contacts", "wall_s", "startup_s", "steady_s",
            "steady_sim_ms", "cost_per_ms_s", "steady_cost_per_ms_s", "phases_s",
            "steady_phases_s", "peak_mb", "loadavg_before", "loadavg_after", "gc_after_remesh",
    "gc_s", "cpu_s", "steady_cpu_s", "steady_cpu_per_ms_s", "regimes")


def regimes(rec: dict) -> dict:
    """Cost per simulated ms and remeshes before the first contact and from it on.

    From the per-step rows of a record (the steps after the warm-up; the Simulation's
    construction is not in them). Before the first contact the block sediments; from
    it on the DEM has contacts and the grains' gaps close (more remeshes).
    """
    ps, w = rec["per_step"], rec["warmup_steps"]
    dt_ms = rec["t_end"] * 1e3 / rec["steps"]
    first = rec["first_contact_step"] or rec["steps"] + 1
    out = {}
    for name, lo, hi in (("sedimenting", w, first - 1), ("contacts", first - 1, rec["steps"])):
        lo = max(lo, w)
        n = hi - lo
        if n <= 0:
            out[name] = None
            continue
        rem = ps["remeshes"][hi - 1] - (ps["remeshes"][lo - 1] if lo > 0 else 0)
        out[name] = {"steps": n, "sim_ms": n * dt_ms, "wall_s": float(sum(ps["wall_s"][lo:hi])),
                     "cost_per_ms_s": float(sum(ps["wall_s"][lo:hi])) / (n * dt_ms),
                     "remeshes": rem, "remeshes_per_ms": rem / (n * dt_ms)}
    return out


def fit_exponent(x, y) -> dict:
    """Least-squares line through ``(log x, log y)``: ``y ~ c x^k``.

    Parameters
    ----------
    x, y : sequence of float
        Positive values, at least two.

    Returns
    -------
    dict
        ``exponent`` k, ``prefactor`` c and ``rms_log_residual`` (natural log).
    """
    lx, ly = np.log(np.asarray(x, float)), np.log(np.asarray(y, float))
    k, lc = np.polyfit(lx, ly, 1)
    res = ly - (k * lx + lc)
    return {"exponent": float(k), "prefactor": float(np.exp(lc)),
            "rms_log_residual": float(np.sqrt(np.mean(res ** 2)))}


def fits(runs: list) -> dict:
    """Growth exponents of cost and memory in the number of grains and of DOFs."""
    g = [r["grains"] for r in runs]
    d = [r["dofs_mean"] for r in runs]
    out = {
        "cost_per_ms_vs_grains": fit_exponent(g, [r["cost_per_ms_s"] for r in runs]),
        "steady_cost_per_ms_vs_grains": fit_exponent(
            g, [r["steady_cost_per_ms_s"] for r in runs]),
        "steady_cost_per_ms_vs_dofs": fit_exponent(d, [r["steady_cost_per_ms_s"] for r in runs]),
        **({"steady_cpu_per_ms_vs_grains": fit_exponent(
            g, [r["steady_cpu_per_ms_s"] for r in runs])}
           if all(r.get("steady_cpu_per_ms_s") for r in runs) else {}),
        "peak_mb_vs_grains": fit_exponent(g, [r["peak_mb"] for r in runs]),
        "dofs_vs_grains": fit_exponent(g, d),
        "remeshes_vs_grains": fit_exponent(g, [max(r["remeshes"], 0.5) for r in runs]),
        "steps_per_ms_vs_grains": fit_exponent(g, [r["steps"] / (r["t_end"] * 1e3)
                                                  for r in runs]),
    }
    phases = sorted({k for r in runs for k in r["steady_phases_s"] if k != "total"})
    for k in phases:
        y = [r["steady_phases_s"].get(k, 0.0) / r["steady_sim_ms"] for r in runs]
        if min(y) > 0:
            out[f"steady_{k}_per_ms_vs_grains"] = fit_exponent(g, y)
    events = [r["steady_factorizations"] + r["steady_jacobian_refreshes"] for r in runs]
    if min(events) > 0:  # one factorisation (BDF2-Stokes operator or Newton Jacobian)
        each = [r["steady_phases_s"]["factorization"] / e
                for r, e in zip(runs, events, strict=True)]
        out["factorization_each_vs_dofs"] = fit_exponent(d, each)
    if min(r["steady_remeshes"] for r in runs) > 0:  # one remesh: mesh, transfer, set-up
        out["remesh_each_vs_dofs"] = fit_exponent(
            d, [(r["steady_phases_s"]["meshing"] + r["steady_phases_s"]["remeshing"])
                / r["steady_remeshes"] for r in runs])
    for k in ("sedimenting", "contacts"):
        reg = [r["regimes"][k] for r in runs]
        if all(reg):
            out[f"{k}_cost_per_ms_vs_grains"] = fit_exponent(g, [x["cost_per_ms_s"] for x in reg])
    return out


def figure(data: dict, path: Path, no_gc: dict | None = None) -> None:
    """Log-log figure: cost per simulated ms and peak memory against grains, fitted slopes.

    Parameters
    ----------
    data : dict
        The results (``runs`` and ``fits``).
    path : Path
        The PNG to write.
    no_gc : dict, optional
        Results of a run without ``gc.collect()`` on the library of 4e84a43 (reference
        cycles): its peak memory is drawn beside.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    runs, f = data["runs"], data["fits"]
    g = np.array([r["grains"] for r in runs], float)
    gg = np.geomspace(g.min(), g.max(), 50)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4.2))
    series = [("cost_per_ms_s", "cost_per_ms_vs_grains", "wall, whole run", "o"),
              ("steady_cost_per_ms_s", "steady_cost_per_ms_vs_grains", "wall, after start-up",
               "s"),
              ("steady_cpu_per_ms_s", "steady_cpu_per_ms_vs_grains", "CPU, after start-up", "^")]
    for key, fit, label, marker in series:
        if fit not in f:
            continue
        fk = f[fit]
        a1.loglog(g, [r[key] for r in runs], marker, mfc="none" if marker == "^" else None,
                  label=f"{label}: slope {fk['exponent']:.2f}")
        a1.loglog(gg, fk["prefactor"] * gg ** fk["exponent"], "-", lw=0.8, color="0.5")
    y0 = runs[0]["steady_cost_per_ms_s"] or runs[0]["cost_per_ms_s"]
    a1.loglog(gg, y0 * gg / g[0], "k:", lw=1, label="slope 1")
    a1.set_ylabel("time per simulated ms (s)")
    fm = f["peak_mb_vs_grains"]
    a2.loglog(g, [r["peak_mb"] for r in runs], "o", label=f"peak RSS: slope {fm['exponent']:.2f}")
    a2.loglog(gg, fm["prefactor"] * gg ** fm["exponent"], "-", lw=0.8, color="0.5")
    if no_gc is not None:
        fn = no_gc["fits"]["peak_mb_vs_grains"]
        a2.loglog([r["grains"] for r in no_gc["runs"]], [r["peak_mb"] for r in no_gc["runs"]],
                  "x", color="C3", label=f"4e84a43 (reference cycles): slope "
                                         f"{fn['exponent']:.2f}")
    a2.loglog(gg, runs[0]["peak_mb"] * gg / g[0], "k:", lw=1, label="slope 1")
    a2.set_ylabel("peak memory (MB)")
    for a in (a1, a2):
        a.set_xlabel("grains")
        a.set_xticks(g, [f"{x:.0f}" for x in g])
        a.xaxis.set_minor_formatter(NullFormatter())
        a.grid(True, which="both", lw=0.3)
        a.legend(fontsize=8)
    fig.suptitle(f"collapse of n x n grains, {runs[-1]['t_end'] * 1e3:.0f} ms each "
                 f"({data['commit']}, 2 shared cores)", fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=130)
    plt.close(fig)


def table(data: dict) -> str:
    """The Markdown table of the runs (as on the benchmarks page)."""
    head = ("| n | grains | vertices | DOFs (start / end / max) | steps | remeshes (travel / "
            "ahead / angle / area) | factorisations / Jacobian refreshes | halvings | wall s "
            "(start-up) | s per sim. ms (steady) | CPU s per sim. ms (steady) | peak MB | "
            "load before / after |")
    rows = [head, "|" + "---|" * 13]
    for r in data["runs"]:
        rr = r["remesh_reasons"] or {}
        rows.append(
            f"| {r['n']} | {r['grains']} | {r['vertices_initial']} / {r['vertices_final']} | "
            f"{r['dofs_initial']} / {r['dofs_final']} / {r['dofs_max']} | {r['steps']} | "
            f"{r['remeshes']} ({rr.get('travel', 0)} / {rr.get('ahead', 0)} / "
            f"{rr.get('angle', 0)} / {rr.get('area', 0)}) | {r['factorizations']} / "
            f"{r['jacobian_refreshes']} | {r['retries']} | {r['wall_s']:.1f} "
            f"({r['startup_s']:.1f}) | {r['cost_per_ms_s']:.3g} "
            f"({r['steady_cost_per_ms_s'] or float('nan'):.3g}) | "
            f"{r.get('steady_cpu_per_ms_s') or float('nan'):.3g} | {r['peak_mb']:.0f} | "
            f"{r['loadavg_before'][0]:.2f} / {r['loadavg_after'][0]:.2f} |")
    return "\n".join(rows)


#: Phases of the phase table, exclusive of each other (``solve_exclusive``: the corrector's
#: triangular solves, residuals and mesh motion; the refreshes' assembly and factorisation
#: are in ``assembly`` and ``factorization``).
PHASES = ("meshing", "remeshing", "assembly", "factorization", "solve_exclusive", "dem",
          "forces")


def phase_table(data: dict) -> str:
    """Markdown table: steady wall time per simulated ms by phase, and its fitted exponent."""
    runs, f = data["runs"], data.get("fits", {})
    head = "| phase | " + " | ".join(f"{r['grains']} grains" for r in runs) + " | exponent |"
    rows = [head, "|" + "---|" * (len(runs) + 2)]
    old = not all("solve_exclusive" in r["steady_phases_s"] for r in runs)
    for k in (*PHASES, "refresh"):
        if old and k in ("solve_exclusive", "refresh"):  # records before the refresh timer
            k = "solve" if k == "solve_exclusive" else None
        if k is None:
            continue
        vals = [r["steady_phases_s"].get(k, 0.0) / r["steady_sim_ms"] for r in runs]
        fk = f.get(f"steady_{k}_per_ms_vs_grains")
        name = {"solve_exclusive": "solve (without refreshes)", "solve": "solve (with refreshes)",
                "refresh": "Jacobian refreshes (in the above)"}.get(k, k)
        slope = f"{fk['exponent']:.2f}" if fk else "-"
        rows.append(f"| {name} | " + " | ".join(f"{v:.3g}" for v in vals) + f" | {slope} |")
    if not old:
        tot = [sum(r["steady_phases_s"].get(k, 0.0) for k in PHASES) / r["steady_sim_ms"]
               for r in runs]
        rows.append("| sum | " + " | ".join(f"{v:.3g}" for v in tot) + " | |")
    return "\n".join(rows)


def check(data: dict) -> None:
    """Assert that every run has every field with a real value and that the fit works.

    Raises
    ------
    AssertionError
        Naming the run and field, or the synthetic power law not recovered.
    """
    for r in data["runs"]:
        for k in RUN_KEYS:
            assert k in r and r[k] is not None, f"n={r.get('n')}: {k} missing"
        for k in ("wall_s", "cost_per_ms_s", "peak_mb", "dofs_initial", "steps"):
            assert np.isfinite(r[k]) and r[k] > 0, f"n={r['n']}: {k} = {r[k]}"
        assert r["status"] == "completed", f"n={r['n']}: status {r['status']}"
        assert len(r["per_step"]["wall_s"]) == r["steps"], f"n={r['n']}: per-step rows"
    x = np.array([25.0, 100.0, 400.0])
    got = fit_exponent(x, 0.03 * x ** 1.17 * np.array([1.0, 1.0 + 1e-9, 1.0]))
    assert abs(got["exponent"] - 1.17) < 1e-6 and abs(got["prefactor"] - 0.03) < 1e-6, got
    for k in ("cost_per_ms_vs_grains", "steady_cost_per_ms_vs_grains", "peak_mb_vs_grains",
              "steady_cost_per_ms_vs_dofs"):
        assert np.isfinite(data["fits"][k]["exponent"]), k
