"""Many collapses: the loose/dense x dry/immersed x core-ratio x seed matrix, on any executor.

:func:`run_collapse_study` sends runs (:class:`~.collapse_run.CollapseRun`,
:func:`~.collapse_run.plan_collapse`) to an executor and keeps their records
(:func:`~.collapse_run.execute_collapse`), with the mean and spread over seeds of every
set-up (:func:`summarise_collapses`), in ``<out>/records.json``. Without an executor the
runs go one after another in this process, where a signal stops the study cleanly at the
end of a step (started again, each run continues from its checkpoint); ``workers > 1``
gives a local process pool; any :class:`concurrent.futures.Executor` takes them too, e.g.
a Dask cluster's (``distributed.Client(...).get_executor()``, the ``cluster`` extra).
Workers share the output folder, so a cluster needs a shared file system.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Iterable
from concurrent.futures import Executor, as_completed
from dataclasses import dataclass, field
from pathlib import Path

from .collapse_run import CollapseRun, execute_collapse

__all__ = ["CollapseStudy", "run_collapse_study", "summarise_collapses"]

#: the record's quantities summarised over seeds per set-up
SUMMARY_KEYS = ("final_runout_mass_front", "froude_max", "t90_over_tau", "cpu_s",
                "solid_fraction")


def summarise_collapses(records: Iterable[dict]) -> list[dict]:
    """Per set-up (state, medium, core ratio): the seeds and, over them, the mean and
    spread (:func:`~skfem_granular.collapse.realisations`) of :data:`SUMMARY_KEYS`."""
    from ..collapse import realisations

    groups: dict = {}
    for r in records:
        groups.setdefault((r["state"], r["medium"], r["core_ratio"]), []).append(r)
    out = []
    for (state, medium, core), rs in sorted(groups.items(), key=lambda kv: str(kv[0])):
        row = {"state": state, "medium": medium, "core_ratio": core,
               "seeds": [r["seed"] for r in rs]}
        for key in SUMMARY_KEYS:
            vals = [r[key] for r in rs if r[key] is not None]
            row[key] = realisations(vals) if vals else None
        out.append(row)
    return out


@dataclass
class CollapseStudy:
    """What :func:`run_collapse_study` did: the finished runs' records (in the order of the
    runs), their summary over seeds, and the runs that did not finish (key -> message:
    ``stopped`` ones continue from their checkpoints when run again)."""

    out_dir: Path
    records: list = field(default_factory=list)
    summary: list = field(default_factory=list)
    stopped: dict = field(default_factory=dict)
    failed: dict = field(default_factory=dict)
    #: the signal (``"SIGINT"``, ``"SIGTERM"``) or budget that stopped a run, if one did
    stopped_by: str | None = None


def _write_records(path: Path, records: list) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps({"records": records, "summary": summarise_collapses(records)},
                              indent=1) + "\n")
    os.replace(tmp, path)


def run_collapse_study(runs: Iterable[CollapseRun], out_dir, *, packings=None,
                       executor: Executor | None = None, workers: int = 1,
                       on_record: Callable[[dict], None] | None = None,
                       log: Callable[[str], None] | None = None) -> CollapseStudy:
    """Run (or continue, or read back) ``runs`` into ``out_dir``; records and summary.

    Parameters
    ----------
    runs : iterable of CollapseRun
        Distinct runs (:func:`plan_collapse`).
    out_dir : str or Path
        Run folders ``out_dir/<key>`` and ``out_dir/records.json`` (every finished
        record and the summary over seeds, rewritten as records arrive).
    packings : str or Path, optional
        Where prepared columns are kept (default ``out_dir/packings``).
    executor : concurrent.futures.Executor, optional
        Where the runs go, e.g. ``distributed.Client(...).get_executor()``.
    workers : int
        Without ``executor``: 1 runs them one after another in this process (a run
        stopped by a signal stops the study; the rest wait for the next start), more
        gives a local pool of that many processes, a fresh one per run.
    on_record : callable, optional
        Called with each finished record as it arrives.
    log : callable, optional
        Called with one line per run that did not finish.
    """
    runs = list(runs)
    if not isinstance(workers, int) or isinstance(workers, bool) or workers < 1:
        raise ValueError(f"workers = {workers!r}: must be an integer >= 1")
    if bad := [r for r in runs if not isinstance(r, CollapseRun)]:
        raise TypeError(f"runs: {type(bad[0]).__name__} given; each must be a CollapseRun")
    keys = [r.key for r in runs]
    if dup := sorted({k for k in keys if keys.count(k) > 1}):
        raise ValueError(f"runs: {', '.join(dup)} given more than once (one folder each)")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    study = CollapseStudy(out_dir)
    done: dict = {}

    def arrived(run: CollapseRun, rec: dict) -> None:
        if rec["status"] == "completed":
            done[run.key] = rec
            _write_records(out_dir / "records.json",
                           [done[k] for k in keys if k in done])
            if on_record is not None:
                on_record(rec)
        else:
            getattr(study, rec["status"])[run.key] = rec["message"]
            if rec["status"] == "stopped":
                study.stopped_by = rec.get("stopped_by")
            if log is not None:
                log(rec["message"])

    if executor is None and workers == 1:
        for run in runs:
            try:
                rec = execute_collapse(run, out_dir, packings)
            except Exception as exc:  # noqa: BLE001 - one failed run must not lose the others
                rec = {"status": "failed", "message": f"{run.key}: {type(exc).__name__}: {exc}"}
            arrived(run, rec)
            if rec["status"] == "stopped":  # asked to stop: the remaining runs wait
                break
    else:
        own = None
        if executor is None:
            from .driver import local_pool

            own = executor = local_pool(workers)
        try:
            futs = {executor.submit(execute_collapse, r, out_dir, packings): r for r in runs}
            for fut in as_completed(futs):
                run = futs[fut]
                try:
                    rec = fut.result()
                except Exception as exc:  # noqa: BLE001 - one failed run must not lose the others
                    rec = {"status": "failed",
                           "message": f"{run.key}: {type(exc).__name__}: {exc}"}
                arrived(run, rec)
        finally:
            if own is not None:
                own.shutdown(wait=True, cancel_futures=True)
    study.records = [done[k] for k in keys if k in done]
    study.summary = summarise_collapses(study.records)
    return study
