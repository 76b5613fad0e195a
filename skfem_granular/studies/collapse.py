"""Many collapses: the loose/dense x dry/immersed x core-ratio x seed matrix, on any executor.

:func:`run_collapse_study` sends runs (:class:`~.collapse_run.CollapseRun`,
:func:`~.collapse_run.plan_collapse`) to an executor and keeps their records
(:func:`~.collapse_run.execute_collapse`), with the mean and spread over seeds of every
set-up (:func:`summarise_collapses`), in ``<out>/records.json``. Without an executor the
runs go one after another in this process; ``workers > 1`` gives a local process pool; any
:class:`concurrent.futures.Executor` takes them too, e.g. a Dask cluster's
(``distributed.Client(...).get_executor()``, the ``cluster`` extra). Workers share the
output folder, so a cluster needs a shared file system.

Stopping. SIGINT or SIGTERM during a run stops it at the end of its step, its checkpoint
written; started again, the study reads the finished runs back and continues the others.
One after another in this process, the study ends with the stopped run. In a local pool,
Ctrl-C in a terminal reaches the workers too (one process group) and each stops at the
end of its step; a signal to this process alone waits for the runs under way. On a Dask
cluster the runs under way finish their task when the client goes.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable
from concurrent.futures import Executor, as_completed
from dataclasses import dataclass, field
from pathlib import Path

from ..io import write_text
from .collapse_run import CollapseRun, cached_packing, check_folder, execute_collapse

__all__ = ["CollapseStudy", "merge_records", "run_collapse_study", "summarise_collapses"]

#: the record's quantities summarised over seeds per set-up
SUMMARY_KEYS = ("final_runout_mass_front", "froude_max", "t90_over_tau", "cpu_s",
                "solid_fraction")


def summarise_collapses(records: Iterable[dict]) -> list[dict]:
    """The mean and spread over seeds of each set-up's records.

    Parameters
    ----------
    records : iterable of dict
        Finished runs' records (:func:`~.collapse_run.execute_collapse`).

    Returns
    -------
    list of dict
        Per set-up (state, medium, core ratio, coupling, rolling friction, contact
        stiffness): ``seeds``
        and, for each of :data:`SUMMARY_KEYS`, :func:`~skfem_granular.collapse.realisations`
        of its values (mean, sample standard deviation, min, max, count; None without
        values).
    """
    from ..collapse import realisations

    groups: dict = {}
    for r in records:
        groups.setdefault((r["state"], r["medium"], r["core_ratio"],
                           r.get("coupling", "monolithic"), r.get("rolling_friction", 0.0),
                           r.get("contact_stiffness", 1e6)), []).append(r)
    out = []
    for (state, medium, core, coupling, mu_r, E), rs in sorted(groups.items(),
                                                              key=lambda kv: str(kv[0])):
        row = {"state": state, "medium": medium, "core_ratio": core, "coupling": coupling,
               "rolling_friction": mu_r, "contact_stiffness": E,
               "seeds": [r["seed"] for r in rs]}
        for key in SUMMARY_KEYS:
            vals = [r[key] for r in rs if r[key] is not None]
            row[key] = realisations(vals) if vals else None
        out.append(row)
    return out


@dataclass
class CollapseStudy:
    """What :func:`run_collapse_study` did.

    Attributes
    ----------
    out_dir : Path
        The study's folder (absolute).
    records : list of dict
        The finished runs' records, in the order of the runs
        (:func:`~.collapse_run.execute_collapse`).
    summary : list of dict
        :func:`summarise_collapses` of ``records``.
    stopped, failed : dict
        Runs that did not finish, key -> one line: ``stopped`` ones continue from their
        checkpoints when run again.
    stopped_by : str or None
        The signal (``"SIGINT"``, ``"SIGTERM"``) or budget that stopped a run, if one did.
    """

    out_dir: Path
    records: list = field(default_factory=list)
    summary: list = field(default_factory=list)
    stopped: dict = field(default_factory=dict)
    failed: dict = field(default_factory=dict)
    stopped_by: str | None = None


def _locked(fh) -> None:
    """Hold an exclusive lock on the open file ``fh`` until it is closed (POSIX; elsewhere
    no lock)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        return
    fcntl.flock(fh, fcntl.LOCK_EX)


def merge_records(path, new: list) -> list:
    """Put the records ``new`` into the file ``path`` (``records.json``) in place of
    earlier records of the same runs, with the summary over all of them; returns them.

    Read, merged and written under an exclusive lock and renamed into place from a unique
    temporary file, so that studies writing into one folder at once (one process per
    packing state, say) keep each other's records.
    """
    path = Path(path)
    with open(path.with_name(f".{path.name}.lock"), "w") as lock:
        _locked(lock)
        try:
            old = json.loads(path.read_text())["records"] if path.exists() else []
        except (json.JSONDecodeError, KeyError, TypeError):
            old = []  # not a records file: the run folders hold every record anyway
        keys = {r["run"] for r in new}
        records = [r for r in old if r["run"] not in keys] + list(new)
        write_text(path, json.dumps({"records": records,
                                     "summary": summarise_collapses(records)}, indent=1) + "\n")
    return records


def _column(run: CollapseRun) -> tuple:
    """What decides a run's packing (runs with the same one share its file)."""
    return (run.n, run.state, run.seed, run.aspect, run.contact_stiffness)


def _prepare(run: CollapseRun, packings: Path) -> None:
    """Prepare the column of ``run`` on a worker (nothing sent back)."""
    cached_packing(run.n, run.state, run.seed, packings, aspect=run.aspect,
                   t_max=run.packing_t_max, E=run.contact_stiffness)


def _prepare_all(executor: Executor, runs: list, packings: Path) -> dict:
    """Each distinct column of ``runs`` prepared once on ``executor`` before the runs start
    (two workers would otherwise prepare the same one at once); column -> error line."""
    jobs = {}
    for r in runs:
        k = _column(r)
        if k not in jobs:
            jobs[k] = executor.submit(_prepare, r, packings)
    errors = {}
    for k, fut in jobs.items():
        try:
            fut.result()
        except Exception as exc:  # noqa: BLE001 - reported on each run that needs it
            errors[k] = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
    return errors


def _failed(run: CollapseRun, why: str) -> dict:
    """The record of a run that failed for ``why``."""
    return {"status": "failed", "message": f"{run.key}: {why}"}


def _checked_runs(runs: Iterable[CollapseRun], workers: int) -> list[CollapseRun]:
    """``runs`` as a list, refused in one line when ``workers`` is not a count >= 1, a run
    is not a :class:`~.collapse_run.CollapseRun` or two runs share a folder."""
    runs = list(runs)
    if not isinstance(workers, int) or isinstance(workers, bool) or workers < 1:
        raise ValueError(f"workers = {workers!r}: must be an integer >= 1")
    if bad := [r for r in runs if not isinstance(r, CollapseRun)]:
        raise TypeError(f"runs: {type(bad[0]).__name__} given; each must be a CollapseRun")
    keys = [r.key for r in runs]
    if dup := sorted({k for k in keys if keys.count(k) > 1}):
        raise ValueError(f"runs: {', '.join(dup)} given more than once (one folder each)")
    return runs


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
        record and the summary over seeds, merged as records arrive:
        :func:`merge_records`). A folder that holds a run of other settings is refused
        before anything runs (:func:`~.collapse_run.check_folder`).
    packings : str or Path, optional
        Where prepared columns are kept (default ``out_dir/packings``).
    executor : concurrent.futures.Executor, optional
        Where the runs go, e.g. ``distributed.Client(...).get_executor()``; its workers
        must see ``out_dir`` (a shared file system; the paths are made absolute here).
        The distinct columns are prepared first, one task each.
    workers : int
        Without ``executor``: 1 runs them one after another in this process (a run
        stopped by a signal stops the study; the rest wait for the next start), more
        gives a local pool of that many processes, a fresh one per run.
    on_record : callable, optional
        Called with each finished record as it arrives.
    log : callable, optional
        Called with one line per run that did not finish.

    Returns
    -------
    CollapseStudy

    Raises
    ------
    ValueError
        Bad ``workers``, a run given twice, or a folder holding other settings.
    TypeError
        Something other than a :class:`~.collapse_run.CollapseRun` among ``runs``.
    """
    runs = _checked_runs(runs, workers)
    out_dir = Path(out_dir).resolve()
    packings = out_dir / "packings" if packings is None else Path(packings).resolve()
    out_dir.mkdir(parents=True, exist_ok=True)
    for r in runs:
        check_folder(r, out_dir / r.key)
    study = CollapseStudy(out_dir)
    done: dict = {}

    def arrived(run: CollapseRun, rec: dict) -> None:
        if rec["status"] == "completed":
            done[run.key] = rec
            merge_records(out_dir / "records.json", [rec])
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
                rec = _failed(run, f"{type(exc).__name__}: {exc}")
            arrived(run, rec)
            if rec["status"] == "stopped":  # asked to stop: the remaining runs wait
                break
    else:
        own = None
        if executor is None:
            from .driver import local_pool

            own = executor = local_pool(workers)
        try:
            unprepared = _prepare_all(executor, runs, packings)
            futs = {}
            for r in runs:
                if (why := unprepared.get(_column(r))) is not None:
                    arrived(r, _failed(r, f"its column could not be prepared: {why}"))
                else:
                    futs[executor.submit(execute_collapse, r, out_dir, packings)] = r
            for fut in as_completed(futs):
                run = futs[fut]
                try:
                    rec = fut.result()
                except Exception as exc:  # noqa: BLE001 - one failed run must not lose the others
                    rec = _failed(run, f"{type(exc).__name__}: {exc}")
                arrived(run, rec)
        finally:
            if own is not None:
                own.shutdown(wait=True, cancel_futures=True)
    study.records = [done[r.key] for r in runs if r.key in done]
    study.summary = summarise_collapses(study.records)
    return study
