"""Benchmark: the unsteady DFG cylinder cases 2D-3 and 2D-2, accuracy against CPU time.

Usage::

    python benchmarks/dfg_cylinder.py [--case 2D-3|2D-2|both] [--levels 0,1,2]
        [--t-end T] [--tag NAME]

Runs :func:`skfem_granular.validation.dfg.run_dfg` on a ladder of meshes and time steps
(:data:`LEVELS_2D3`, :data:`LEVELS_2D2`: cylinder polygon sides, largest element size,
size at the outlet, fixed step) and reports, per level, the DOFs, steps, the CPU time of
the time loop and the errors against the references: John (2004) for 2D-3
(``c_D,max = 2.950921575``, ``c_L,max = 0.47795``, their times, ``dp(8) = -0.1116``),
the intervals of Schaefer & Turek (1996) for 2D-2 (``c_D,max`` [3.22, 3.24],
``c_L,max`` [0.99, 1.01], ``St`` [0.295, 0.305]). The acceptance levels are 0.1 % on
``c_D,max`` and 1 % on ``c_L,max`` for 2D-3 and the intervals for 2D-2.

2D-2 levels start from one spin-up run on the coarsest mesh (:data:`PRECURSOR_2D2`, t = 0
to 8, its cost reported apart) and run 5 time units (15 shedding periods) on their own
mesh; the last 5 periods are evaluated.

One thread (OMP/MKL/OPENBLAS/NUMBA threads 1 unless set), one level after the other in
this process. Writes ``benchmarks/results/dfg_cylinder_<tag>.json`` after every level
(commit, machine, load averages, every level's numbers and its time series) and prints
a markdown table.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402 - the thread limits must be set before numpy loads
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from record import commit, machine  # noqa: E402

from skfem_granular.validation import dfg  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

#: 2D-3 level -> (polygon sides, h_max, h_outlet, dt)
LEVELS_2D3 = {0: (32, 0.04, None, 0.02), 1: (64, 0.025, None, 0.01),
              2: (128, 0.015, None, 0.005), 3: (128, 0.015, None, 0.0025),
              4: (128, 0.015, None, 0.00125), 5: (256, 0.01, 0.02, 0.00125)}
#: 2D-2 level -> (polygon sides, h_max, h_outlet, dt)
LEVELS_2D2 = {0: (64, 0.025, None, 0.01), 1: (128, 0.015, None, 0.005),
              2: (128, 0.015, None, 0.0025), 3: (128, 0.01, 0.02, 0.0025),
              4: (128, 0.007, 0.02, 0.0025)}
#: 2D-2 spin-up, run once: (sides, h_max, h_outlet, dt, t_end). Every 2D-2 level starts
#: from its last flow (interpolated) and runs to T_END_2D2; the last 5 lift periods are
#: evaluated. Measured on the 128-gon, h_max 0.015, dt 0.005: c_L,max 0.97248 after
#: 4 time units from the spin-up against 0.97255 after 12 from rest.
PRECURSOR_2D2 = (64, 0.025, None, 0.01, 8.0)
T_END_2D2 = 13.0

#: at most this many samples of each time series go into the JSON (every k-th step)
SERIES_SAMPLES = 1600

#: acceptance: relative errors of the 2D-3 maxima
ACCEPT_2D3 = {"cd_max": 1e-3, "cl_max": 1e-2}


def precursor() -> tuple[dfg.DFGSeries, dict]:
    """The 2D-2 spin-up from rest (:data:`PRECURSOR_2D2`) and its record."""
    sides, h_max, h_out, dt, t_end = PRECURSOR_2D2
    s = dfg.run_dfg("2D-2", dfg.channel_mesh(sides, h_max, h_outlet=h_out), dt, t_end)
    return s, {"sides": sides, "h_max": h_max, "dt": dt, "t_end": t_end, "dofs": s.dofs,
               "steps": s.steps, "cpu_time_s": s.cpu_time, "wall_time_s": s.wall_time}


def run_level(case: str, level: int, t_end: float | None, start=None) -> dict:
    """One level: mesh, run (2D-2 from ``start``), summary; the series thinned for the JSON."""
    sides, h_max, h_out, dt = (LEVELS_2D3 if case == "2D-3" else LEVELS_2D2)[level]
    cpu0 = time.process_time()
    mesh = dfg.channel_mesh(sides, h_max, h_outlet=h_out)
    mesh_cpu = time.process_time() - cpu0
    load0 = os.getloadavg()
    s = dfg.run_dfg(case, mesh, dt, t_end if t_end is not None else
                    (None if case == "2D-3" else T_END_2D2), initial=start)
    if case == "2D-3":
        summary = dfg.dfg2d3_summary(s)
        summary["accepted"] = all(abs(summary[f"err_{k}"]) <= tol
                                  for k, tol in ACCEPT_2D3.items())
    else:
        summary = dfg.dfg2d2_summary(s)
        summary["accepted"] = all(summary["within"].values())
    return {"case": case, "level": level, "sides": sides, "h_max": h_max, "h_outlet": h_out,
            "dt": dt, "dofs": s.dofs, "triangles": s.triangles, "steps": s.steps,
            "rejected": s.rejected, "refreshes": s.refreshes, "iterations": s.iterations,
            "dt_min": s.info["dt_min"], "cpu_time_s": s.cpu_time, "wall_time_s": s.wall_time,
            "mesh_cpu_s": mesh_cpu, "loadavg_before": load0, "loadavg_after": os.getloadavg(),
            "summary": summary,
            "series_stride": (k := -(-s.steps // SERIES_SAMPLES)),
            "series": {v: np.round(getattr(s, v)[::k], 7).tolist()
                       for v in ("t", "cd", "cl", "dp")}}


def row(r: dict) -> str:
    s = r["summary"]
    head = (f"| {r['case']} | {r['level']} | {r['sides']} | {r['h_max']:g}"
            f"{'' if r['h_outlet'] is None else '/' + format(r['h_outlet'], 'g')} | "
            f"{r['dofs']} | {r['dt']:g} | {r['steps']} | {r['cpu_time_s']:.0f} | ")
    if r["case"] == "2D-3":
        return head + (f"{s['cd_max']:.5f} ({100 * s['err_cd_max']:+.3f} %) at "
                       f"{s['t_cd_max']:.4f} | {s['cl_max']:.5f} ({100 * s['err_cl_max']:+.2f} %)"
                       f" at {s['t_cl_max']:.4f} | dp(8) {s['dp_end']:.4f} | "
                       f"{'yes' if s['accepted'] else 'no'} |")
    return head + (f"{s['cd_max']:.4f} | {s['cl_max']:.4f} | St {s['strouhal']:.4f} | "
                   f"{'yes' if s['accepted'] else 'no'} |")


def table(levels: list[dict]) -> str:
    rows = ["| case | level | sides | h_max[/h_out] | DOFs | dt | steps | CPU [s] | c_D,max | "
            "c_L,max | other | accepted |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    return "\n".join(rows + [row(r) for r in levels])


def parse_levels(text: str, case: str) -> list[int]:
    table_ = LEVELS_2D3 if case == "2D-3" else LEVELS_2D2
    try:
        levels = [int(v) for v in text.split(",")]
    except ValueError:
        raise SystemExit(f"--levels {text!r}: expected comma-separated integers") from None
    bad = [lv for lv in levels if lv not in table_]
    if bad:
        raise SystemExit(f"--levels {text!r}: {case} levels are {sorted(table_)}")
    return levels


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--case", choices=("2D-3", "2D-2", "both"), default="2D-3")
    ap.add_argument("--levels", default="0,1,2", help="comma-separated level numbers")
    ap.add_argument("--levels-2d2", default=None, help="levels of 2D-2 with --case both")
    ap.add_argument("--t-end", type=float, default=None,
                    help="end time (default 8 for 2D-3, 13 for 2D-2)")
    ap.add_argument("--tag", default="default")
    args = ap.parse_args(argv)
    cases = ["2D-3", "2D-2"] if args.case == "both" else [args.case]
    plan = [(c, lv) for c in cases for lv in parse_levels(
        args.levels_2d2 if (c == "2D-2" and args.levels_2d2) else args.levels, c)]
    out_path = ROOT / "benchmarks" / "results" / f"dfg_cylinder_{args.tag}.json"
    res = {"benchmark": "DFG 2D-3 / 2D-2 cylinder, P2/P1 Taylor-Hood, BDF2, fixed steps",
           "commit": commit(), "machine": machine(), "loadavg_start": os.getloadavg(),
           "reference_2d3": dfg.DFG2D3_REFERENCE, "intervals_2d2": dfg.DFG2D2_INTERVALS,
           "acceptance_2d3": ACCEPT_2D3, "levels": []}
    start = None
    for case, lv in plan:
        if case == "2D-2" and start is None:
            pre, res["precursor_2d2"] = precursor()
            start = pre.flow
            print(f"2D-2 spin-up: {res['precursor_2d2']}", flush=True)
        r = run_level(case, lv, args.t_end, start if case == "2D-2" else None)
        res["levels"].append(r)
        print(row(r), flush=True)
        res["table"] = table(res["levels"])
        out_path.write_text(json.dumps(res, indent=1) + "\n")
    print(res["table"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
