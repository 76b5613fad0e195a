"""The progress bar of a run: tqdm, its clock started after the first step."""

from __future__ import annotations

__all__ = ["count_step", "progress_bar"]


def progress_bar(name: str, n_steps: int, progress: bool | None):
    """A tqdm bar of ``n_steps`` steps named ``name``, shown when ``progress`` is true
    (``None``: when there are more than 50 steps); the notebook widget where tqdm.auto
    finds one."""
    show = n_steps > 50 if progress is None else progress
    if show:
        from tqdm.auto import tqdm
    else:
        from tqdm import tqdm
    return tqdm(total=n_steps, disable=not show, desc=name, unit="step")


def count_step(bar) -> None:
    """One step done on ``bar``. The first step of a process includes compiling or loading
    the kernels and building the first systems: the bar's clock starts again after it, so
    the time left it shows comes from the steps that follow (the first is counted as done,
    tqdm's ``initial``)."""
    if not bar.disable and bar.n == bar.initial == 0:
        bar.reset()
        bar.initial = bar.n = bar.last_print_n = 1
        bar.refresh()
    else:
        bar.update(1)
