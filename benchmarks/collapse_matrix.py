"""Loose against dense, dry against immersed: the collapse matrix over core ratios and seeds.

Usage::

    python benchmarks/collapse_matrix.py --smoke            # 30 grains, 4 ms: the pipeline
    python benchmarks/collapse_matrix.py                    # 200 grains, a = 0.8, 8 tau_c
    python benchmarks/collapse_matrix.py --cores 0.8 --seeds 0 --media immersed
    python benchmarks/collapse_matrix.py --n 1000 --cores 0.9 --seeds 0 --to-rest --tag n1000
    python benchmarks/collapse_matrix.py --workers 2          # two runs at once, locally
    python benchmarks/collapse_matrix.py --scheduler tcp://host:8786   # on a Dask cluster

The runs are :class:`skfem_granular.studies.CollapseRun` sent through
:func:`skfem_granular.studies.run_collapse_study` (one after another in this process by
default; ``--workers`` local processes; ``--scheduler`` a Dask cluster's workers, which
must see this checkout's folders). Every run is a column of ``--n`` grains
(:func:`skfem_granular.packing.prepare_column`, 12-gon near-disks, d_max / d_min = 1.8,
aspect 0.8; the packings are kept in ``results/packings/``) released behind its gate
(:func:`skfem_granular.collapse.column_scene`) dry or in water, the immersed runs at each
core ratio (the dry ones need none). A run writes its output folder
``out/collapse_matrix_<tag>/<run>`` (or ``--folder``/<run>) with a checkpoint every
``--checkpoint-every`` steps:
a run cut off is continued where its checkpoint stands the next time this script is
started (:meth:`Simulation.resume`), a finished one is read back, not run again. Per run
the JSON records the cost (CPU, wall, DOFs, steps) and the run-out series
(:func:`skfem_granular.collapse.collapse_series`); ``cpu_s`` and ``wall_s`` are summed
over the processes that ran it (kept in its folder's ``cost.json``); per set-up (state,
medium, core ratio) the final run-out (the deposit's mass front,
:func:`skfem_granular.collapse.mass_front`), the largest front Froude number and the time
to 90 % of the final run-out as mean and spread over the seeds
(:func:`skfem_granular.collapse.realisations`). Results:
``benchmarks/results/collapse_matrix_<tag>.json``.

With ``--to-rest`` a run ends when the grains' kinetic energy has fallen below
``--stop-ratio`` of its peak after ``--t-min`` (in tau_c), or at ``--t-max``; its folder
then keeps ``rest.json`` (when, the energy ratio, whether at rest) and its record says
``at_rest``. The records also carry the run's phase times (``phases_s``, summed over its
processes), factorisations, Jacobian refreshes, the largest mesh and the peak memory.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from skfem_granular.studies import plan_collapse, run_collapse_study, summarise_collapses

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks/results"
PACKINGS = RESULTS / "packings"
ASPECT = 0.8


def packing(n: int, state: str, seed: int, t_max: float = 3.0):
    """The column (prepared once, then read from ``results/packings/``; ``t_max``: the
    deposition's time limit, :func:`~skfem_granular.packing.prepare_column`)."""
    from skfem_granular.studies import cached_packing

    return cached_packing(n, state, seed, PACKINGS, aspect=ASPECT, t_max=t_max)


def earlier_runs(out: Path) -> list:
    """The runs already in the results file (kept when their output folders are gone)."""
    return json.loads(out.read_text())["runs"] if out.exists() else []


def record(out: Path, rec: dict) -> None:
    """Put ``rec`` into the results file in place of an earlier record of the same run.

    The file is read, updated and written under an exclusive lock, so that several
    processes working through different runs of one matrix (``--states dense`` in one,
    ``--states loose`` in another) keep each other's records.
    """
    import fcntl

    lock_path = ROOT / "out" / f"{out.stem}.lock"
    lock_path.parent.mkdir(parents=True, exist_ok=True)
    with open(lock_path, "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        runs = [r for r in earlier_runs(out) if r["run"] != rec["run"]] + [rec]
        out.write_text(json.dumps({"benchmark": "collapse_matrix", "aspect": ASPECT,
                                   "cpus": os.cpu_count(), "runs": runs,
                                   "summary": summarise_collapses(runs)}, indent=1)
                       + "\n")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--states", nargs="+", default=["dense", "loose"])
    ap.add_argument("--media", nargs="+", default=["dry", "immersed"])
    ap.add_argument("--cores", type=float, nargs="+", default=[0.7, 0.8, 0.9, 0.95])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--tau", type=float, default=8.0, help="run length in tau_c")
    ap.add_argument("--checkpoint-every", type=int, default=200)
    ap.add_argument("--tag", default=None)
    ap.add_argument("--folder", type=Path, default=None,
                    help="the runs' folders (default out/collapse_matrix_<tag>; runs that "
                         "must outlive this checkout: a folder outside it)")
    ap.add_argument("--coupling", default="monolithic", choices=["monolithic", "split"],
                    help="the immersed runs' coupled solver")
    ap.add_argument("--smoke", action="store_true", help="30 grains, 0.1 tau_c, seed 0")
    ap.add_argument("--mu-r", type=float, default=0.0,
                    help="rolling friction coefficient of the contacts (0: free rolling)")
    ap.add_argument("--stiffness", type=float, default=1e6,
                    help="contact stiffness E of the packings (N/m; stiffer: less overlap)")
    ap.add_argument("--to-rest", action="store_true",
                    help="end a run when its kinetic energy is below --stop-ratio of its peak")
    ap.add_argument("--stop-ratio", type=float, default=1e-3)
    ap.add_argument("--t-min", type=float, default=3.0, help="earliest rest, in tau_c")
    ap.add_argument("--t-max", type=float, default=20.0, help="latest end with --to-rest")
    ap.add_argument("--packing-t-max", type=float, default=3.0,
                    help="deposition time limit (s) of a packing prepared here")
    ap.add_argument("--workers", type=int, default=1,
                    help="runs at once in local processes (1: one after another here)")
    ap.add_argument("--scheduler", default=None,
                    help="a Dask scheduler's address: the runs go to its workers")
    a = ap.parse_args(argv)
    if a.smoke:
        a.n, a.seeds, a.tau, a.cores, a.checkpoint_every = 30, [0], 0.1, [0.8], 10
    tag = a.tag or ("smoke" if a.smoke else f"n{a.n}")
    out = RESULTS / f"collapse_matrix_{tag}.json"
    try:
        runs = plan_collapse(a.n, states=a.states, media=a.media, cores=a.cores,
                             seeds=a.seeds, aspect=ASPECT,
                             t_end_tau=a.t_max if a.to_rest else a.tau, to_rest=a.to_rest,
                             stop_ratio=a.stop_ratio, t_min_tau=a.t_min,
                             checkpoint_every=a.checkpoint_every,
                             packing_t_max=a.packing_t_max, coupling=a.coupling,
                             rolling_friction=a.mu_r, contact_stiffness=a.stiffness)
    except ValueError as exc:
        ap.error(str(exc))

    def recorded(rec: dict) -> None:
        print(json.dumps({k: v for k, v in rec.items() if k != "series"}), flush=True)
        record(out, rec)

    client = None
    if a.scheduler:
        from distributed import Client  # the cluster extra

        client = Client(a.scheduler)
    try:
        folder = a.folder or ROOT / "out" / f"collapse_matrix_{tag}"
        study = run_collapse_study(runs, folder,
                                   packings=PACKINGS, workers=a.workers,
                                   executor=client.get_executor() if client else None,
                                   on_record=recorded, log=lambda line: print(line, flush=True))
    except ValueError as exc:
        ap.error(str(exc))
    finally:
        if client is not None:
            client.close()
    if not (study.stopped or study.failed):
        print(f"wrote {out}")


if __name__ == "__main__":
    main()
