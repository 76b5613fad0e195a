"""A run's checkpoint copied into a scratch folder, to be resumed there (the run itself is
not touched): what the benchmarks that measure a window of a long run share."""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


def run_argument(ap: argparse.ArgumentParser) -> None:
    """The positional ``run`` argument: a run's output folder with ``checkpoint.npz``."""
    ap.add_argument("run", type=Path, help="a run's output folder with checkpoint.npz")


def check_run(run: Path, **counts: int) -> None:
    """Exit with one line when ``run`` has no checkpoint or a count (``--steps`` and the
    like, by name) is below 1."""
    if not (run / "checkpoint.npz").exists():
        sys.exit(f"run: {run} has no checkpoint.npz")
    for name, n in counts.items():
        if n < 1:
            sys.exit(f"--{name} = {n}: must be at least 1")


@contextmanager
def scratch_copy(run: Path, prefix: str) -> Iterator[Path]:
    """A temporary folder holding ``run``'s checkpoint and the history.csv it follows."""
    with tempfile.TemporaryDirectory(prefix=prefix) as tmp:
        folder = Path(tmp) / run.name
        folder.mkdir()
        shutil.copy2(run / "checkpoint.npz", folder / "checkpoint.npz")
        if (run / "history.csv").exists():  # a checkpoint of version 4 follows its rows
            shutil.copy2(run / "history.csv", folder / "history.csv")
        yield folder
