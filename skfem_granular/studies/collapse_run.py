"""One collapse of the matrix: :class:`CollapseRun`, :func:`plan_collapse` and
:func:`execute_collapse`, the worker function :mod:`.collapse` sends to an executor.

A run is one column of ``n`` grains prepared by a seeded protocol
(:func:`~skfem_granular.packing.prepare_column`, 12-gon near-disks, ``d_max / d_min =
1.8``), released behind its gate dry or in water (:func:`~skfem_granular.collapse.column_scene`)
and run for ``t_end_tau`` times ``tau_c`` or, with ``to_rest``, until the grains' kinetic
energy has fallen below ``stop_ratio`` of its peak. :func:`execute_collapse` runs one,
continues it from the checkpoint in its folder, or reads a finished one back, and returns
its record: the cost (CPU and wall time summed over every process that ran it, DOFs,
phases, peak memory), the poorest mesh any step ended on (immersed runs: smallest angle
and area ratio, over the steps counted in ``mesh_steps_checked``) and what collapse
experiments report (final run-out at the mass
front and the gap front, largest front Froude number, time to 90 % of the run-out, the
run-out and kinetic-energy series).
"""


from __future__ import annotations

import json
import resource
import time
from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..io import write_text

__all__ = ["MEDIA", "STATES", "CollapseRun", "cached_packing", "check_folder",
           "execute_collapse", "plan_collapse"]

STATES = ("dense", "loose")
MEDIA = ("dry", "immersed")


@dataclass(frozen=True)
class CollapseRun:
    """One collapse of the matrix.

    Parameters
    ----------
    n : int
        Grains in the column (>= 2).
    state : {"dense", "loose"}
        The packing protocol (:data:`~skfem_granular.packing.PROTOCOLS`).
    medium : {"dry", "immersed"}
        DEM alone, or grains in water.
    seed : int
        The packing's seed (sizes, shapes, orientations, start positions).
    core_ratio : float
        Immersed: the fluid's outline of a grain over its contact outline, in (0, 1]; a
        dry run has none (1).
    aspect : float
        The column's ``H0 / L0`` the packing aims at (> 0).
    t_end_tau : float
        The run's end in ``tau_c = sqrt(H0 / g)`` (with ``to_rest``: the latest end).
    to_rest : bool
        End the run when the grains' kinetic energy falls below ``stop_ratio`` of its peak,
        after ``t_min_tau``.
    stop_ratio, t_min_tau : float
        The rest criterion: ``stop_ratio`` in (0, 1), ``0 <= t_min_tau < t_end_tau``.
    checkpoint_every, vtu_every : int
        Steps between checkpoints (a run cut off continues from its last one) and between
        saved frames (>= 1).
    packing_t_max : float
        The deposition's time limit (s) when the packing is prepared (> 0).
    coupling : {"monolithic", "split"}
        Immersed: the coupled solver (``Scene.coupling``); ``"split"`` for many grains.
    rolling_friction : float
        The contacts' rolling friction coefficient ``mu_r`` (>= 0; 0: free rolling).
    contact_stiffness : float
        The packing's contact stiffness ``E`` (N/m, > 0), with which it is prepared and
        run: stiffer contacts overlap less (a core ratio of 0.95 needs them) and take
        more DEM substeps (``sqrt(E)``).
    """

    n: int
    state: str
    medium: str
    seed: int = 0
    core_ratio: float = 1.0
    aspect: float = 0.8
    t_end_tau: float = 8.0
    to_rest: bool = False
    stop_ratio: float = 1e-3
    t_min_tau: float = 3.0
    checkpoint_every: int = 200
    vtu_every: int = 250
    packing_t_max: float = 3.0
    coupling: str = "monolithic"
    rolling_friction: float = 0.0
    contact_stiffness: float = 1e6

    def __post_init__(self):
        # plain Python numbers (a numpy integer from np.arange would not go into JSON)
        for name, low in (("n", 2), ("seed", 0), ("checkpoint_every", 1), ("vtu_every", 1)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < low:
                raise ValueError(f"{name} = {v!r}: must be an integer >= {low}")
            object.__setattr__(self, name, int(v))
        for name in ("core_ratio", "aspect", "t_end_tau", "stop_ratio", "t_min_tau",
                     "packing_t_max", "rolling_friction", "contact_stiffness"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
                raise ValueError(f"{name} = {v!r}: must be a number")
            object.__setattr__(self, name, float(v))
        if not isinstance(self.to_rest, (bool, np.bool_)):
            raise ValueError(f"to_rest = {self.to_rest!r}: must be True or False")
        object.__setattr__(self, "to_rest", bool(self.to_rest))
        if self.state not in STATES:
            raise ValueError(f"state = {self.state!r}: must be one of {', '.join(STATES)}")
        if self.coupling not in ("monolithic", "split"):
            raise ValueError(f"coupling = {self.coupling!r}: must be 'monolithic' or 'split'")
        if self.medium not in MEDIA:
            raise ValueError(f"medium = {self.medium!r}: must be one of {', '.join(MEDIA)}")
        if self.medium == "dry" and self.core_ratio != 1.0:
            raise ValueError(f"core_ratio = {self.core_ratio!r}: a dry run has no fluid "
                             "outline; leave it at 1")
        if not 0.0 < self.core_ratio <= 1.0:
            raise ValueError(f"core_ratio = {self.core_ratio!r}: must be in (0, 1]")
        for name in ("aspect", "t_end_tau", "packing_t_max", "contact_stiffness"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} = {v!r}: must be finite and > 0")
        if not (np.isfinite(self.rolling_friction) and self.rolling_friction >= 0):
            raise ValueError(f"rolling_friction = {self.rolling_friction!r}: must be finite "
                             "and >= 0")
        if self.to_rest:
            if not 0.0 < self.stop_ratio < 1.0:
                raise ValueError(f"stop_ratio = {self.stop_ratio!r}: must be in (0, 1)")
            if not 0.0 <= self.t_min_tau < self.t_end_tau:
                raise ValueError(f"t_min_tau = {self.t_min_tau!r}: must satisfy 0 <= "
                                 f"t_min_tau < t_end_tau = {self.t_end_tau!r}")

    @property
    def key(self) -> str:
        """The run's name and its folder's: ``dense_dry_s0``, ``loose_immersed_core0.9_s2``,
        ``dense_dry_s1_mur0.1``, ``dense_immersed_core0.95_s0_E1e+07``."""
        core = f"_core{self.core_ratio:g}" if self.medium == "immersed" else ""
        solver = "_split" if self.medium == "immersed" and self.coupling == "split" else ""
        rolling = f"_mur{self.rolling_friction:g}" if self.rolling_friction else ""
        stiff = f"_E{self.contact_stiffness:g}" if self.contact_stiffness != 1e6 else ""
        return f"{self.state}_{self.medium}{core}_s{self.seed}{solver}{rolling}{stiff}"


def _choices(name: str, values) -> list:
    """``values`` as a non-empty list (a single string or number is refused by name)."""
    if isinstance(values, (str, bytes, int, float)) or not isinstance(values, Iterable):
        raise ValueError(f"{name} = {values!r}: must be a list of values")
    values = list(values)
    if not values:
        raise ValueError(f"{name} = []: must name at least one value")
    if len({repr(v) for v in values}) < len(values):
        raise ValueError(f"{name} = {values!r}: each value once")
    return values


def plan_collapse(n: int, *, states: Iterable[str] = STATES, media: Iterable[str] = MEDIA,
                  cores: Iterable[float] = (0.7, 0.8, 0.9, 0.95),
                  seeds: Iterable[int] = (0, 1, 2), **options) -> list[CollapseRun]:
    """The matrix: per seed, per state, per medium the runs (immersed: one per core ratio).

    Parameters
    ----------
    n : int
        Grains per column.
    states, media, cores, seeds : lists
        The axes of the matrix (``cores``: the immersed runs' core ratios; the dry runs
        have none). Each a non-empty list.
    **options
        The other fields of :class:`CollapseRun`, the same for every run.

    Returns
    -------
    list of CollapseRun
        Seed by seed, state by state, medium by medium.
    """
    states, media, seeds = (_choices(k, v) for k, v in
                            (("states", states), ("media", media), ("seeds", seeds)))
    cores = _choices("cores", cores) if "immersed" in media else [1.0]
    return [CollapseRun(n, state, medium, seed, core, **options)
            for seed in seeds for state in states for medium in media
            for core in (cores if medium == "immersed" else (1.0,))]


def check_folder(run: CollapseRun, folder) -> None:
    """Refuse a run folder holding a run of other settings; record this run's there.

    The folder's name is the run's :attr:`~CollapseRun.key` (state, medium, core ratio,
    seed); the other settings that decide its numbers (grains, aspect, length, rest
    criterion) are kept in ``run.json`` when it starts, and a later run of other settings
    into the same folder is refused in one line naming them (it would be read back, or
    continued, as if it were the run asked for). A folder from before ``run.json`` is
    taken as the run asked for.
    """
    folder = Path(folder)
    spec = {k: getattr(run, k) for k in _DECIDING}
    path = folder / "run.json"
    if path.exists():
        held = json.loads(path.read_text())
        if diff := [k for k in _DECIDING if held.get(k) != spec[k]]:
            raise ValueError(
                f"{run.key}: the folder {str(folder)!r} holds this run with "
                + ", ".join(f"{k} = {held.get(k)!r}" for k in diff) + " (asked: "
                + ", ".join(f"{k} = {spec[k]!r}" for k in diff)
                + "); use another output folder for other settings")
        return
    write_text(path, json.dumps(spec) + "\n")


#: the settings of a run besides its key that decide its numbers (checked by check_folder)
_DECIDING = ("n", "aspect", "t_end_tau", "to_rest", "stop_ratio", "t_min_tau")


# ---------------------------------------------------------------------------------- one run
def cached_packing(n: int, state: str, seed: int, packings, *, aspect: float = 0.8,
                   t_max: float = 3.0, d_mean: float = 1e-3, E: float = 1e6):
    """The column of ``n`` grains prepared once, then read back.

    Parameters
    ----------
    n, state, seed, aspect, d_mean, E
        As :func:`~skfem_granular.packing.prepare_column` takes them (12-gon near-disks,
        its defaults otherwise); they name the file
        ``<state>_a<aspect>_n<n>_seed<seed>.npz``, with ``_d<d_mean in mm>mm`` and
        ``_E<E>`` before ``.npz`` where they are not the defaults (1 mm, 1e6 N/m).
    packings : str or Path
        The folder of prepared columns.
    t_max : float
        The deposition's time limit (s): a limit, not a setting of the result (a column
        that has not come to rest by then is an error), so not part of the name.

    Returns
    -------
    Packing

    Notes
    -----
    The file is written under a unique temporary name and renamed into place, so
    processes (or hosts sharing the folder) preparing the same column at once leave one
    whole file.
    """
    from ..packing import load_packing, prepare_column

    name = (f"{state}_a{aspect:g}_n{n}_seed{seed}" + (f"_d{d_mean * 1e3:g}mm" if d_mean != 1e-3
                                                      else "") + (f"_E{E:g}" if E != 1e6 else ""))
    path = Path(packings) / f"{name}.npz"
    if path.exists():
        return load_packing(path)
    pk = prepare_column(n, aspect, state, seed=seed, t_max=t_max, d_mean=d_mean, E=E)
    pk.save(path)  # atomically: preparers of the same column at once leave one whole file
    return pk


def _finished(folder: Path) -> bool:
    """Whether the run in ``folder`` reached its end (its summary says so, or it came to
    rest: ``rest.json``)."""
    if (folder / "rest.json").exists():
        return True
    path = folder / "summary.json"
    return path.exists() and json.loads(path.read_text()).get("status") == "completed"


def _energy_peak(pk, folder: Path) -> float:
    """The largest kinetic energy in the run's history so far (0 for a new run)."""
    from ..collapse import history_columns, kinetic_energies, masses

    path = folder / "history.csv"
    if not path.exists():
        return 0.0
    c = history_columns(path)
    m, J = masses(pk)
    return max((sum(kinetic_energies(m, J, (vx, vy), w))
                for vx, vy, w in zip(c["vx"], c["vy"], c["omega"], strict=True)), default=0.0)


def _simulation(run: CollapseRun, pk, t_end: float, folder: Path):
    """A new run into ``folder``, or the run continued from its checkpoint there."""
    from ..collapse import column_scene
    from ..simulation import Simulation

    if (folder / "checkpoint.npz").exists():
        return Simulation.resume(folder)
    scene = column_scene(pk, fluid=run.medium == "immersed", core_ratio=run.core_ratio,
                         mu_r=run.rolling_friction, t_end=t_end, name=folder.name,
                         output_dir=str(folder), vtu_every=run.vtu_every)
    scene = replace(scene, checkpoint_every=run.checkpoint_every)
    if run.medium == "immersed":
        scene = replace(scene, coupling=run.coupling)
    return Simulation(scene, overwrite=True)


def _measure(pk, folder: Path, domain) -> dict:
    """Run-out series and the final deposit of a finished run, from its files."""
    from ..collapse import (
        collapse_series,
        grain_outlines,
        history_columns,
        local_outlines,
        mass_front,
    )

    cols = history_columns(folder / "history.csv")
    s = collapse_series(cols, pk, domain)
    local, _ = local_outlines(pk)
    final = grain_outlines(local, cols["x"][-1], cols["y"][-1], cols["angle"][-1])
    L_end = mass_front([P - np.array([[domain[0]], [domain[1]]]) for P in final])
    r_end = (L_end - pk.width) / pk.width
    reach = s["runout"] >= 0.9 * r_end
    return {"final_runout_mass_front": float(r_end),
            "final_runout_gap_front": float(s["runout"][-1]),
            "froude_max": float(np.nanmax(s["froude"])),
            "t90_over_tau": float(s["t_over_tau"][np.argmax(reach)]) if reach.any() else None,
            "series": {k: np.asarray(s[k]).tolist()
                       for k in ("t_over_tau", "runout", "E_x", "E_y", "froude")}}


def _add_cost(folder: Path, cpu: float, wall: float, dofs: list, phases: dict,
              mesh: dict | None = None) -> dict:
    """Add this process's share to the run's ``cost.json`` and return the totals.

    ``mesh``: this process's ``summary.json`` mesh entry; its poorest mesh over the
    steps (``min_angle_over_steps``, ``min_area_ratio_over_steps``) is folded into the
    run's (``mesh_min_angle``, ``mesh_min_area_ratio`` over ``mesh_steps_checked``)."""
    path = folder / "cost.json"
    c: dict[str, Any] = json.loads(path.read_text()) if path.exists() else {
        "cpu_s": 0.0, "wall_s": 0.0, "processes": 0, "dofs_sum": 0, "dofs_steps": 0}
    c.setdefault("phases_s", {})
    if dofs:  # a process that stepped (not one that only read a finished run back)
        c["cpu_s"] += cpu
        c["wall_s"] += wall
        c["processes"] += 1
        c["dofs_sum"] += int(np.sum(dofs))
        c["dofs_steps"] += len(dofs)
        c["dofs_max"] = max(c.get("dofs_max", 0), int(np.max(dofs)))
        c["peak_mb"] = max(c.get("peak_mb", 0.0),
                           resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
        for k, v in phases.items():
            c["phases_s"][k] = c["phases_s"].get(k, 0.0) + float(v)
        if mesh and mesh.get("steps_checked"):
            for key, ours in (("mesh_min_angle", "min_angle_over_steps"),
                              ("mesh_min_area_ratio", "min_area_ratio_over_steps")):
                c[key] = min(c.get(key, float("inf")), float(mesh[ours]))
            c["mesh_steps_checked"] = c.get("mesh_steps_checked", 0) + mesh["steps_checked"]
        write_text(path, json.dumps(c) + "\n")
    return {"cpu_s": c["cpu_s"], "wall_s": c["wall_s"], "processes": c["processes"],
            "dofs_mean": c["dofs_sum"] / c["dofs_steps"] if c["dofs_sum"] else None,
            "dofs_max": c.get("dofs_max"), "peak_mb": c.get("peak_mb"),
            "phases_s": c["phases_s"],
            **{k: c.get(k) for k in ("mesh_min_angle", "mesh_min_area_ratio",
                                     "mesh_steps_checked")}}


def execute_collapse(run: CollapseRun, out_dir, packings=None) -> dict:
    """Run, continue or read back one collapse and measure it (the worker function).

    Parameters
    ----------
    run : CollapseRun
    out_dir : str or Path
        The run's folder is ``out_dir / run.key`` (frames, history, checkpoints,
        ``cost.json``; ``rest.json`` once at rest).
    packings : str or Path, optional
        Where prepared columns are kept (default ``out_dir / "packings"``).

    Returns
    -------
    dict
        ``status`` ``"completed"`` with the measurements (module notes); otherwise
        ``"stopped"`` (by a signal or a budget: its checkpoint is kept, run it again to
        continue) or ``"failed"``, with ``message`` and the ``steps`` done.
    """
    from ..collapse import column_scene, time_scale

    out_dir = Path(out_dir)
    check_folder(run, out_dir / run.key)
    pk = cached_packing(run.n, run.state, run.seed,
                        out_dir / "packings" if packings is None else packings,
                        aspect=run.aspect, t_max=run.packing_t_max, E=run.contact_stiffness)
    folder = out_dir / run.key
    c0, w0, dofs, phases = time.process_time(), time.perf_counter(), [], {}
    tau = time_scale(pk)
    if _finished(folder):
        domain = column_scene(pk, fluid=False).domain
    else:
        sim = _simulation(run, pk, run.t_end_tau * tau, folder)
        domain = sim.scene.domain
        peak = _energy_peak(pk, folder) if run.to_rest else 0.0
        steps = sim.evolve(progress=False)
        for t, _ in steps:
            dofs.append(int(sim.space.N) if run.medium == "immersed" else 0)
            if run.to_rest:
                E = sim.dem.kinetic_energy()
                peak = max(peak, E)
                if t > run.t_min_tau * tau and E < run.stop_ratio * peak:
                    steps.close()  # at rest: the files are completed by the generator
                    write_text(folder / "rest.json", json.dumps(
                        {"t": t, "t_over_tau": t / tau, "energy_ratio": E / peak,
                         "stop_ratio": run.stop_ratio, "at_rest": True,
                         "steps": sim.steps_done}) + "\n")
                    break
        phases = dict(sim.result.summary.get("wall_time", {})) if sim.result else {}
    summary = json.loads((folder / "summary.json").read_text())
    cost = _add_cost(folder, time.process_time() - c0, time.perf_counter() - w0, dofs, phases,
                     summary.get("mesh") if dofs else None)
    rest = (json.loads((folder / "rest.json").read_text())
            if (folder / "rest.json").exists() else None)
    if rest is not None:
        summary["status"] = "completed"  # at rest before its latest end: the run's end
    if summary.get("status") != "completed":
        failed = summary.get("status") == "failed"
        why = (f"failed: {summary.get('failed')}" if failed else
               f"stopped by {summary.get('stopped_by')}; start again to continue")
        return {"run": run.key, "status": "failed" if failed else "stopped",
                "steps": summary.get("steps"), "stopped_by": summary.get("stopped_by"),
                "message": f"{run.key}: {summary.get('status')} at step "
                           f"{summary.get('steps')} ({why})"}
    rec = {"run": run.key, "state": run.state, "medium": run.medium,
           "core_ratio": run.core_ratio, "coupling": run.coupling, "seed": run.seed,
           "rolling_friction": run.rolling_friction, "contact_stiffness": pk.E, "grains": pk.n,
           "solid_fraction": pk.solid_fraction, "tau_c": tau, **cost,
           "steps": summary.get("steps"), "remeshes": summary.get("remeshes"),
           "factorizations": summary.get("factorizations"),
           "jacobian_refreshes": summary.get("jacobian_refreshes"),
           "retries": summary.get("retries"),
           "t_end_over_tau": summary.get("t_end", 0.0) / tau}
    if run.to_rest:
        rec["at_rest"] = rest is not None
        if rest is not None:
            rec["energy_ratio"] = rest["energy_ratio"]
    rec.update(_measure(pk, folder, domain))
    return {"status": "completed", **rec}


