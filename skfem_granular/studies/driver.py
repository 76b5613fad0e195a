"""The study on the client side: :func:`run_study` sends the runs to an executor,
keeps each record as it arrives (``<out>/runs/<key>.json``, resumable) and writes
the tables and figures.

A study's folder belongs to it (:class:`StudyFolder`), as a run's output folder
belongs to the run: ``study.json`` names the study; a folder holding another
study's output is refused unless told to replace it (``overwrite``), one
holding a simulation run's output always; while the study runs, the folder's
lock (:class:`~skfem_granular.simulation.folder.FolderLock`) refuses a second
live writer.
"""

from __future__ import annotations

import json
from concurrent.futures import Executor, as_completed
from dataclasses import asdict, dataclass
from pathlib import Path

from ..io import remove_partial_files, write_text
from ..simulation.folder import (
    STUDY_FORMAT,
    STUDY_MARKER,
    FolderInUseError,
    FolderLock,
    HeldFolder,
    run_files,
    study_in,
)
from .analysis import analyse
from .definitions import Run, plan
from .plots import all_plots, require_matplotlib
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


#: The files a study writes in its folder, besides ``runs/<key>.json``.
STUDY_FILE_NAMES = (STUDY_MARKER, "table.csv", "table.md", "pareto.png", "convergence.png",
                    "fig2.png")


def study_files(out_dir) -> list[Path]:
    """A study's files in ``out_dir``: :data:`STUDY_FILE_NAMES` and ``runs/*.json``."""
    d = Path(out_dir)
    found = [d / n for n in STUDY_FILE_NAMES if (d / n).is_file()]
    return found + (sorted((d / "runs").glob("*.json")) if (d / "runs").is_dir() else [])


def _names(paths) -> str:
    return ", ".join(p.name for p in paths[:3]) + (", ..." if len(paths) > 3 else "")


class StudyFolder(HeldFolder):
    """The folder of one study: ownership checks, the lock, ``study.json``.

    Parameters
    ----------
    out_dir : str or Path
    study : str
    smoke : bool
        Part of the study's identity (another grid of runs).
    overwrite : bool
        Replace another study's output (its files are removed when the folder is
        taken); the same study's output is continued either way, and replaced too
        with ``overwrite``.
    """

    def __init__(self, out_dir, study: str, smoke: bool = False, overwrite: bool = False):
        self.directory = Path(out_dir)
        self.identity = {"format": STUDY_FORMAT, "study": study, "smoke": bool(smoke)}
        self.overwrite = overwrite
        self.lock = FolderLock(self.directory, "study")

    def _held(self) -> dict | None:
        """The identity of the study whose output the folder holds (``None``: none, or one
        from before ``study.json``: its ``table.md`` title tells, else taken as this one)."""
        held = study_in(self.directory)
        if held is not None:
            return {k: held.get(k) for k in self.identity}
        try:
            title = (self.directory / "table.md").read_text().partition("\n")[0]
        except OSError:
            return None
        study, sep, rest = title.removeprefix("# ").partition(" study")
        if not title.startswith("# ") or not sep or rest not in ("", " (smoke)"):
            return None  # not a study's table
        return {"format": STUDY_FORMAT, "study": study, "smoke": rest == " (smoke)"}

    def check(self) -> None:
        """Refuse (:class:`FolderInUseError`, one line) a folder this study may not write to:
        a simulation run's, another study's (unless ``overwrite``), a live writer's."""
        self._check_files()
        self.lock.check()

    def _check_files(self) -> None:
        d = self.directory
        found = run_files(d)
        if found:
            raise FolderInUseError(
                f"output folder {str(d)!r}: holds a simulation run's output ({_names(found)}); "
                "a study needs a folder of its own")
        held = self._held()
        if held is not None and held != self.identity and not self.overwrite:
            name = f"{held['study']}{' (smoke)' if held['smoke'] else ''}"
            raise FolderInUseError(
                f"output folder {str(d)!r}: holds the output of another study ({name}: "
                f"{_names(study_files(d))}); use --overwrite (library: overwrite=True) to "
                "replace it, or another folder")

    def acquire(self) -> None:
        """Check the folder, take its lock, clean up (and the old study's files: overwrite)."""
        self.check()
        self.lock.acquire()
        try:
            self._check_files()  # another writer may have finished into it meanwhile
            for d in (self.directory, self.directory / "runs"):
                remove_partial_files(d)
            if self.overwrite:
                for f in study_files(self.directory):
                    f.unlink()
            write_text(self.directory / STUDY_MARKER, json.dumps(self.identity) + "\n")
        except BaseException:
            self.lock.release()
            raise


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
              workers: int = 2, plots: bool = True, log=None, runs=None,
              overwrite: bool = False) -> StudyResult:
    """Run (or resume) ``study`` into ``out_dir``; table, plots and per-run JSON.

    The folder belongs to the study (:class:`StudyFolder`): one that holds a simulation
    run's output, or another study's (unless ``overwrite``), or that a live process is
    writing to, is refused with a one-line
    :class:`~skfem_granular.simulation.folder.FolderInUseError` before any run.

    Parameters
    ----------
    executor : concurrent.futures.Executor, optional
        Where the runs go, e.g. ``dask.distributed.Client(...).get_executor()``;
        default a local process pool of ``workers`` processes, a fresh one per run.
    runs : list of Run, optional
        A subset (or another grid) instead of :func:`plan`'s.
    plots : bool
        Write the figures too (matplotlib, the ``plot`` extra: checked before the first
        run, ImportError if missing).
    overwrite : bool
        Remove the study output in ``out_dir`` first (another study's, or this one's:
        every run is computed again).
    """
    runs = plan(study, smoke) if runs is None else list(runs)
    if not isinstance(workers, int) or isinstance(workers, bool) or workers < 1:
        raise ValueError(f"workers = {workers!r}: must be an integer >= 1")
    if plots:
        require_matplotlib()
    out_dir = Path(out_dir)
    with StudyFolder(out_dir, study, smoke, overwrite):
        return _run_study(study, out_dir, runs, smoke, executor, workers, plots, log)


def _run_study(study, out_dir: Path, runs, smoke, executor, workers, plots, log) -> StudyResult:
    """:func:`run_study` in the folder it holds."""
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
