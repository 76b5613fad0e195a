"""The study on the client side: :func:`run_study` sends the runs to an executor,
keeps each record as it arrives (``<out>/runs/<key>.json``, resumable) and writes
the tables and figures."""

from __future__ import annotations

import json
from concurrent.futures import Executor, as_completed
from dataclasses import asdict, dataclass
from pathlib import Path

from ..io import write_text
from .analysis import analyse
from .definitions import Run, plan
from .plots import all_plots
from .tables import write_tables
from .worker import execute


@dataclass
class StudyResult:
    """Rows of the table, the files written and which runs were computed this time."""

    study: str
    out_dir: Path
    rows: list
    computed: list
    failed: dict
    files: list


def _record_path(out_dir: Path, run: Run) -> Path:
    return out_dir / "runs" / f"{run.key}.json"


def load_records(out_dir, runs) -> dict:
    """Finished records of ``runs`` found in ``out_dir/runs`` (key -> record)."""
    out = {}
    for r in runs:
        p = _record_path(Path(out_dir), r)
        if p.exists():
            try:
                rec = json.loads(p.read_text())
            except json.JSONDecodeError:
                continue  # a torn file from an interrupted write: recompute
            if rec.get("spec") == asdict(r):
                out[r.key] = rec
    return out


def run_study(study: str, out_dir, *, smoke: bool = False, executor: Executor | None = None,
              workers: int = 2, plots: bool = True, log=None, runs=None) -> StudyResult:
    """Run (or resume) ``study`` into ``out_dir``; table, plots and per-run JSON.

    Parameters
    ----------
    executor : concurrent.futures.Executor, optional
        Where the runs go, e.g. ``dask.distributed.Client(...).get_executor()``;
        default a local process pool of ``workers`` processes, a fresh one per run.
    runs : list of Run, optional
        A subset (or another grid) instead of :func:`plan`'s.
    """
    runs = plan(study, smoke) if runs is None else list(runs)
    if not isinstance(workers, int) or isinstance(workers, bool) or workers < 1:
        raise ValueError(f"workers = {workers!r}: must be an integer >= 1")
    out_dir = Path(out_dir)
    (out_dir / "runs").mkdir(parents=True, exist_ok=True)
    done = load_records(out_dir, runs)
    todo = [r for r in runs if r.key not in done]
    computed, failed = [], {}
    own = None
    if todo and executor is None:
        own = executor = local_pool(workers)
    try:
        # no executor only when there is nothing to do
        futs = {} if executor is None else {executor.submit(execute, study, r): r for r in todo}
        for fut in as_completed(futs):
            r = futs[fut]
            try:
                rec = fut.result()
            except Exception as exc:  # noqa: BLE001 - one failed run must not lose the others
                failed[r.key] = f"{type(exc).__name__}: {exc}"
                continue
            _write_json(_record_path(out_dir, r), rec)
            done[r.key] = rec
            computed.append(r.key)
            if log:
                log(f"{r.key}: {rec['dofs']} DOFs, {rec['wall']['total']:.2f} s")
    finally:
        if own is not None:
            own.shutdown(wait=True, cancel_futures=True)
    rows = analyse(study, runs, done)
    files = write_tables(rows, out_dir, study, smoke)
    if plots and rows:
        files += all_plots(rows, out_dir, study)
    return StudyResult(study, out_dir, rows, computed, failed, files)


def local_pool(workers: int) -> Executor:
    """The default executor: ``workers`` forkserver processes, a fresh one per run
    (so that each run's peak memory is its own)."""
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(["skfem_granular.studies", "skfem_granular.simulation", "meshing"])
    return ProcessPoolExecutor(workers, mp_context=ctx, max_tasks_per_child=1)


def _write_json(path, rec):
    """A run's record, written atomically (a failure leaves no file, never a torn one)."""
    write_text(path, json.dumps(rec, indent=1))
