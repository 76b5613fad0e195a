"""Scaling of contact-dominated flow: immersed column collapses of 25 to 1000 grains.

:mod:`scaling` times blocks of grains that sediment before they touch; this benchmark
times the flow that collapses, heaps and avalanches are made of. Each run is a dense
column (:func:`skfem_granular.packing.prepare_column`: 12-gon near-disks, d_mean = 1 mm,
d_max / d_min = 1.8, aspect 0.8, seed 0) released in water at ``t = 0``
(:func:`skfem_granular.collapse.column_scene`, core ratio 0.9, the collapse
experiment's default mesh and step of 0.2 ms): every grain touches its neighbours from
the first step, so every step of the window is a contact step. The packings are kept in
``results/packings/`` (prepared once; the 1000-grain one takes several minutes).

Each run is a subprocess of its own (its ``ru_maxrss`` is its peak memory) and
simulates :data:`WINDOW_STEPS` steps; the cost per simulated millisecond (wall and CPU)
is taken after :data:`WARMUP` steps, with the DOFs, remeshes, factorisations, Jacobian
refreshes and the fraction of steps with contacts. Growth exponents are least-squares
slopes on log-log axes (:func:`scaling_report.fits`).

Usage::

    python benchmarks/scaling_contact.py                  # 25 100 400 1000 grains
    python benchmarks/scaling_contact.py --n 25 100       # -> results/scaling_contact.json
    python benchmarks/scaling_contact.py --n 400 --append # add a run to the file
    python benchmarks/scaling_contact.py --steps 12 --n 25 --out /tmp/x.json   # quick look
    python benchmarks/scaling_contact.py --coupling monolithic split --n 100 400 \
        --out benchmarks/results/split_scaling_contact.json   # the two solvers in turn

With several ``--coupling`` values the runs of one grain count follow each other (the
solvers interleaved on the same machine state), and the fits are per solver.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

from scaling import commit_id, simulate
from scaling_report import fit_exponent

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks/results"
PACKINGS = RESULTS / "packings"

GRAINS = (25, 100, 400, 1000)
ASPECT = 0.8
CORE_RATIO = 0.9
DT = 2e-4
#: Steps simulated per run, and the first of them counted as start-up.
WINDOW_STEPS = 30
WARMUP = 5


def packing(n: int, seed: int = 0):
    """The dense column of ``n`` grains (prepared once, then read from ``PACKINGS``)."""
    from skfem_granular.packing import load_packing, prepare_column

    path = PACKINGS / f"dense_a{ASPECT:g}_n{n}_seed{seed}.npz"
    if path.exists():
        return load_packing(path)
    # the solid fraction is measured 2 d_max from the edges, or 0.5 d_max in the small columns
    pk = prepare_column(n, ASPECT, "dense", seed=seed)
    PACKINGS.mkdir(parents=True, exist_ok=True)
    pk.save(path)
    return pk


def set_stall_rule(rule: str | None) -> None:
    """``"rate:R"`` or ``"amortised:N"``: the chord iteration's stall rule
    (:class:`skfem_granular.fluid.newton.ChordStall`) in place of the library's default."""
    from skfem_granular.fluid import newton

    if rule is None:
        return
    kind, _, value = rule.partition(":")
    newton.STALL_RULE = kind
    if kind == "rate":
        newton.STALL_RATE = float(value)
    elif kind == "amortised":
        newton.REFRESH_ITERATIONS = float(value)
    else:
        raise SystemExit(f"--stall-rule: 'rate:R' or 'amortised:N', not {rule!r}")


def child(n: int, steps: int, stall_rule: str | None = None,
          coupling: str = "monolithic") -> dict:
    """One collapse window in this process: the record of :func:`scaling.simulate`.

    ``stall_rule``: see :func:`set_stall_rule` (a comparison of the rules); ``coupling``:
    the scene's coupled solver.
    """
    from dataclasses import replace

    from skfem_granular.collapse import column_scene

    set_stall_rule(stall_rule)

    pk = packing(n)
    scene = column_scene(pk, fluid=True, core_ratio=CORE_RATIO, t_end=steps * DT, dt=DT,
                         name=f"collapse_contact_{n}")
    rec = simulate(n, steps * DT, WARMUP, log=sys.stderr,
                   scene=replace(scene, coupling=coupling))
    rec["coupling"] = coupling
    c = rec["per_step"]["contacts"]
    rec["contact_step_fraction"] = sum(1 for k in c if k > 0) / max(len(c), 1)
    rec["solid_fraction"] = pk.solid_fraction
    rec["packing"] = {"n": pk.n, "aspect": pk.aspect, "state": pk.state}
    rec["stall_rule"] = stall_rule or "library"
    # the cost of a refresh in chord iterations, as measured in this window
    it, ref = rec["steady_iterations"], rec["steady_jacobian_refreshes"]
    ph = rec["steady_phases_s"]
    if it and ref:
        rec["refresh_over_iteration"] = (ph["refresh"] / ref) / (ph["solve_exclusive"] / it)
    return rec


def run_child(n: int, steps: int, stall_rule: str | None = None,
              coupling: str = "monolithic") -> dict:
    """:func:`child` in a fresh interpreter, with the load average around it."""
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", str(n), str(steps),
           "--coupling", coupling]
    if stall_rule is not None:
        cmd += ["--stall-rule", stall_rule]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        p for p in (str(ROOT), str(ROOT / "benchmarks"), os.environ.get("PYTHONPATH")) if p)}
    load0 = list(os.getloadavg())
    out = subprocess.run(cmd, check=True, stdout=subprocess.PIPE, text=True, env=env)
    rec = json.loads(out.stdout.strip().splitlines()[-1])
    rec["loadavg_before"], rec["loadavg_after"] = load0, list(os.getloadavg())
    return rec


def fits(runs: list) -> dict:
    """Growth exponents in the number of grains (and the solve cost in the DOFs), per
    coupled solver when the runs have several."""
    solvers = sorted({r.get("coupling", "monolithic") for r in runs})
    if len(solvers) > 1:
        return {s: fits([r for r in runs if r.get("coupling", "monolithic") == s])
                for s in solvers}
    if len(runs) < 2:
        return {}
    g = [r["grains"] for r in runs]
    return {
        "steady_cost_per_ms_vs_grains": fit_exponent(g, [r["steady_cost_per_ms_s"] for r in runs]),
        "steady_cpu_per_ms_vs_grains": fit_exponent(g, [r["steady_cpu_per_ms_s"] for r in runs]),
        "steady_cost_per_ms_vs_dofs": fit_exponent([r["dofs_mean"] for r in runs],
                                                   [r["steady_cost_per_ms_s"] for r in runs]),
        "dofs_vs_grains": fit_exponent(g, [r["dofs_mean"] for r in runs]),
        "peak_mb_vs_grains": fit_exponent(g, [r["peak_mb"] for r in runs]),
    }


def table(data: dict) -> str:
    """The runs as a plain-text table."""
    rows = ["grains  coupling    dofs_mean  steps  contact%  remeshes  factor  refresh  "
            "s/ms(wall)  s/ms(cpu)  peak_MB"]
    for r in data["runs"]:
        rows.append(f"{r['grains']:6d}  {r.get('coupling', 'monolithic'):10s} "
                    f"{r['dofs_mean']:10.0f} {r['steps']:6d} "
                    f"{100 * r['contact_step_fraction']:8.0f} {r['remeshes']:9d} "
                    f"{r['steady_factorizations']:7d} {r['steady_jacobian_refreshes']:8d} "
                    f"{r['steady_cost_per_ms_s']:11.2f} {r['steady_cpu_per_ms_s']:10.2f} "
                    f"{r['peak_mb']:8.0f}")
    return "\n".join(rows)


def main(argv=None) -> dict | None:
    """Command line (see the module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+", default=list(GRAINS), help="grains per run")
    ap.add_argument("--steps", type=int, default=WINDOW_STEPS, help="steps per run")
    ap.add_argument("--out", type=Path, default=RESULTS / "scaling_contact.json")
    ap.add_argument("--append", action="store_true",
                    help="keep the runs of --out of other grain counts (one fit over all)")
    ap.add_argument("--stall-rule", default=None,
                    help="'rate:R' or 'amortised:N': the chord iteration's stall rule in place "
                         "of the library's (a comparison)")
    ap.add_argument("--coupling", nargs="+", default=["monolithic"],
                    choices=["monolithic", "split"], help="coupled solvers, in turn per run")
    ap.add_argument("--child", nargs=2, metavar=("N", "STEPS"), help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        print(json.dumps(child(int(a.child[0]), int(a.child[1]), a.stall_rule,
                               a.coupling[0])))
        return None
    data = {"benchmark": "scaling_contact", "commit": commit_id(), "cpus": os.cpu_count(),
            "aspect": ASPECT, "core_ratio": CORE_RATIO, "dt": DT, "warmup_steps": WARMUP,
            "runs": []}
    if a.append and a.out.exists():
        data["runs"] = [r for r in json.loads(a.out.read_text())["runs"] if r["grains"] not in a.n]
    for n in a.n:
        for coupling in a.coupling:
            data["runs"].append(run_child(n, a.steps, a.stall_rule, coupling))
        data["runs"].sort(key=lambda r: (r["grains"], r.get("coupling", "monolithic")))
        data["fits"] = fits(data["runs"])
        a.out.parent.mkdir(parents=True, exist_ok=True)
        a.out.write_text(json.dumps(data, indent=1) + "\n")  # kept after every run
        print(table(data), flush=True)
    print(json.dumps(data["fits"], indent=1))
    return data


if __name__ == "__main__":
    main()
