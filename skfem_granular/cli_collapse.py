"""``skfem-granular collapse``: the loose/dense x dry/immersed matrix from the command line.

``skfem-granular collapse N --out DIR [--states dense loose] [--media dry immersed]
[--cores 0.7 0.9] [--seeds 0 1 2] [--tau 8] [--to-rest [--stop-ratio R] [--t-min T]]
[--checkpoint-every K] [--workers W | --scheduler ADDRESS]`` runs (or continues, or reads
back) the collapses of :func:`skfem_granular.studies.plan_collapse` with
:func:`skfem_granular.studies.run_collapse_study`, prints one line per finished run and
the mean and spread over the seeds of each set-up, and leaves every record in
``DIR/records.json``. ``--tau`` is the run length in ``tau_c`` (default 8; with
``--to-rest`` the latest end, default 20). Exit code 0 when every run finished, 1 when one
failed, 2 for bad input (one line), 130 / 143 when SIGINT / SIGTERM stopped the study (run
the same command again to continue).
"""

from __future__ import annotations

import sys

from ._validate import MAX_SEED, MAX_WORKERS, in_range

__all__ = ["add_parser", "run"]

#: exit codes of a study stopped by a signal (128 + its number, as for a run)
SIGNAL_EXIT = {"SIGINT": 130, "SIGTERM": 143}


def add_parser(sub) -> None:
    """The ``collapse`` subcommand's arguments on ``sub`` (argparse subparsers)."""
    c = sub.add_parser("collapse", help="the loose/dense x dry/immersed collapse matrix")
    c.add_argument("n", type=int, help="grains per column")
    c.add_argument("--out", required=True, help="the study's folder (run folders, records)")
    c.add_argument("--states", nargs="+", default=["dense", "loose"])
    c.add_argument("--media", nargs="+", default=["dry", "immersed"])
    c.add_argument("--cores", type=float, nargs="+", default=[0.7, 0.9],
                   help="core ratios of the immersed runs (default 0.7 0.9)")
    c.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    c.add_argument("--aspect", type=float, default=0.8, help="H0 / L0 (default 0.8)")
    c.add_argument("--tau", type=float, default=None,
                   help="run length in tau_c (default 8; with --to-rest the latest end, "
                        "default 20)")
    c.add_argument("--to-rest", action="store_true",
                   help="end a run when its kinetic energy is below --stop-ratio of its peak")
    c.add_argument("--stop-ratio", type=float, default=1e-3)
    c.add_argument("--t-min", type=float, default=3.0, help="earliest rest, in tau_c")
    c.add_argument("--checkpoint-every", type=int, default=200)
    where = c.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=1,
                       help="runs at once in local processes (1: one after another here)")
    where.add_argument("--scheduler", help="a Dask scheduler's address (the cluster extra)")


def run(args) -> int:
    """Run the ``collapse`` subcommand; returns the exit code."""
    from .signals import StopNow
    from .studies import plan_collapse, run_collapse_study

    tau = args.tau if args.tau is not None else (20.0 if args.to_rest else 8.0)
    client = None
    try:
        _check_numbers(args, tau)
        runs = plan_collapse(args.n, states=args.states, media=args.media, cores=args.cores,
                             seeds=args.seeds, aspect=args.aspect, t_end_tau=tau,
                             to_rest=args.to_rest, stop_ratio=args.stop_ratio,
                             t_min_tau=args.t_min, checkpoint_every=args.checkpoint_every)
        if args.scheduler:
            client = _client(args.scheduler)
        study = run_collapse_study(runs, args.out, workers=args.workers,
                                   executor=client.get_executor() if client else None,
                                   on_record=_print_record,
                                   log=lambda m: print(m, flush=True))
    except (ValueError, TypeError, OSError) as exc:
        print(f"skfem-granular: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    except StopNow as exc:  # between runs (preparing a column, reading a run back)
        print(f"skfem-granular: stopped by {exc.name} between runs; the records so far are "
              f"in {args.out}/records.json (the same command continues)", file=sys.stderr)
        return exc.exit_status
    finally:
        if client is not None:
            client.close()
    for row in study.summary:
        print(_summary_line(row))
    print(f"{len(study.records)} of {len(runs)} runs finished; records in "
          f"{study.out_dir / 'records.json'}")
    if study.failed:
        return 1
    if study.stopped:
        return SIGNAL_EXIT.get(study.stopped_by or "", 1)
    return 0


#: Longest run, in tau_c (the bundled runs go to 20).
MAX_TAU = 1000.0


def _check_numbers(args, tau: float) -> None:
    """Every number of the command line in its range (one line naming the option)."""
    from .scene.parse import MAX_PARTICLES

    in_range("n", args.n, 2, MAX_PARTICLES, integer=True)
    for core in args.cores:
        in_range("--cores", core, 0, 1, open_lo=True)
    for seed in args.seeds:
        in_range("--seeds", seed, 0, MAX_SEED, integer=True)
    in_range("--aspect", args.aspect, 0.05, 20)
    in_range("--tau", tau, 0, MAX_TAU, open_lo=True)
    in_range("--stop-ratio", args.stop_ratio, 0, 1, open_lo=True, open_hi=True)
    if args.to_rest:  # the earliest rest, before the latest end
        in_range("--t-min", args.t_min, 0, tau, open_hi=True)
    else:
        in_range("--t-min", args.t_min, 0, MAX_TAU)
    in_range("--checkpoint-every", args.checkpoint_every, 1, integer=True)
    in_range("--workers", args.workers, 1, MAX_WORKERS, integer=True)


def _client(address: str):
    """A Dask client of the scheduler at ``address`` (one-line errors naming --scheduler)."""
    try:
        from distributed import Client
    except ImportError:
        raise ValueError("--scheduler: needs Dask's distributed (pip install "
                         "'skfem-granular[cluster]')") from None
    try:
        return Client(address, timeout="10s")
    except (OSError, ValueError, TypeError) as exc:
        raise ValueError(f"--scheduler = {address!r}: no Dask scheduler there "
                         f"({type(exc).__name__}: {exc})") from None


def _print_record(rec: dict) -> None:
    print(f"{rec['run']}: solid fraction {rec['solid_fraction']:.3f}, run-out "
          f"{rec['final_runout_mass_front']:.3f} (mass front) / "
          f"{rec['final_runout_gap_front']:.3f} (gap front) at "
          f"{rec['t_end_over_tau']:.2f} tau_c, {rec['steps']} steps, "
          f"{rec['cpu_s']:.0f} CPU s", flush=True)


def _summary_line(row: dict) -> str:
    r = row["final_runout_mass_front"]
    spread = f" +- {r['std']:.3f}" if r["std"] is not None else ""
    medium = row["medium"] + (f", core {row['core_ratio']:g}" if row["medium"] == "immersed"
                              else "")
    return (f"{row['state']} {medium}: run-out {r['mean']:.3f}{spread} "
            f"({r['min']:.3f} - {r['max']:.3f}) over seeds {row['seeds']}")
