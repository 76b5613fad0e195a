"""The ``skfem-granular`` command.

- ``skfem-granular run SCENE [--mesh graded|uniform|group] [--out DIR] [--t-end T] [--dt DT]
  [--tol TOL] [--vtu-every N] [--checkpoint-every N]`` runs a scene (a TOML file, or the name
  of a bundled scene: ``run single-particle``) and writes ``flow.pvd`` (VTU frames),
  ``particles.pvd``, ``history.csv`` (growing as the run goes) and ``summary.json`` into the
  output directory, and ``checkpoint.npz`` every N steps;
  ``skfem-granular run --resume DIR [--t-end T]`` continues from its checkpoint (not to a
  time before it). An output directory belongs to one run: a run refuses one that holds
  another run's files unless given ``--overwrite`` (the old files are removed first) and
  refuses one a live run is writing to (its lock file).
  SIGINT (Ctrl-C) or SIGTERM stop a run at the end of the current step with everything
  written and a checkpoint to resume from; a second signal stops it at once (history and
  summary written, the last checkpoint kept); the exit code is then 128 + the signal's
  number (130, 143), also for a signal during start-up. A run that fails (a step that does
  not converge, output that cannot be written: a full disk) exits with code 1 and one line.
- ``skfem-granular scenes`` lists the bundled scenes (name and first comment line).
- ``skfem-granular render DIR --png PATH | --animation PATH [--fps F] [--every N]`` draws a
  run's output; the picture is written under a temporary name and renamed when complete
  (a failed write: exit code 1, an earlier file of that name left as it was).
- ``skfem-granular study single-particle|faxen [--out DIR] [--smoke] [--workers N]
  [--overwrite]`` runs (or continues) an accuracy-vs-cost study. Its folder belongs to it:
  one holding a simulation run's output is refused, one holding another study's unless
  given ``--overwrite``, one a live process writes to (its lock file) always.
- ``skfem-granular collapse N --out DIR [...]`` runs the loose/dense x dry/immersed collapse
  matrix (:mod:`skfem_granular.cli_collapse`).
- ``skfem-granular pack N --out FILE.npz [--aspect A] [--state dense|loose] [--shape S]
  [--seed K] [--size-ratio R] [--d-mean D] [--margin M] [--scene FILE.toml [--dry]]``
  prepares a column of N grains with the DEM alone, saves it and prints its solid
  fraction; ``--scene`` also writes a collapse scene using it
  (:mod:`skfem_granular.cli_pack`).

Bad input ends with exit code 2 and one line naming the field and the allowed range.
"""

from __future__ import annotations

import argparse
import gc
import sys
from dataclasses import replace


class _UsageError(Exception):
    """A bad command line (reported in one line, like bad scene values)."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise _UsageError(message)


def _parser() -> argparse.ArgumentParser:
    p = _Parser(
        prog="skfem-granular", description="Polygonal particles in fluid on graded FEM meshes."
    )
    sub = p.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a scene (TOML)")
    run.add_argument("scene", nargs="?",
                     help="scene file (path/to/scene.toml) or bundled scene name, e.g. "
                          "single-particle (see 'skfem-granular scenes')")
    run.add_argument("--resume", metavar="DIR",
                     help="continue the run whose checkpoint.npz is in DIR (--t-end may extend it)")
    run.add_argument("--mesh", choices=["auto", "graded", "uniform", "group", "field"],
                     help="override mesh.kind")
    run.add_argument("--mesh-motion", choices=["auto", "ale", "fixed"],
                     help="override coupling.mesh_motion (ale: the mesh follows the particles)")
    run.add_argument("--out", help="output directory (default: the scene's output.directory)")
    run.add_argument("--overwrite", action="store_true",
                     help="replace another run's output in the output directory (its files are "
                          "removed first)")
    run.add_argument("--t-end", type=float, help="override time.t_end (s)")
    run.add_argument("--dt", type=float, help="override time.dt (s)")
    run.add_argument("--tol", type=float,
                     help="adaptive steps with this local error tolerance (time.adaptive, "
                          "time.tol); time.dt becomes the first and largest step")
    run.add_argument("--vtu-every", type=int, metavar="N",
                     help="override output.vtu_every: a frame every N steps (0: the last only)")
    run.add_argument("--checkpoint-every", type=int, metavar="N",
                     help="override output.checkpoint_every: checkpoint.npz every N steps "
                          "(0: none; SIGINT/SIGTERM always write one)")
    run.add_argument("--max-steps", type=float, metavar="N",
                     help="refuse a run of more time steps than this (default 1e5)")
    run.add_argument("--max-elements", type=float, metavar="N",
                     help="refuse a mesh of more triangles than this (estimated before "
                          "meshing; default 2e6)")
    run.add_argument("--max-memory", type=float, metavar="GB",
                     help="refuse a run whose peak memory would exceed this (estimated "
                          "before meshing and again from the mesh; default: the memory this "
                          "machine has available)")
    run.add_argument("--no-progress", action="store_true", help="no progress bar")
    sub.add_parser("scenes", help="list the bundled scenes (names for 'run')")
    from .cli_collapse import add_parser as add_collapse
    from .cli_pack import add_parser as add_pack
    from .cli_render import add_parser as add_render

    add_pack(sub)
    add_render(sub)
    add_collapse(sub)
    stu = sub.add_parser("study", help="accuracy against cost over a grid of discretisations")
    stu.add_argument("study", choices=["single-particle", "faxen"])
    stu.add_argument("--out", help="study directory (default: out/study_<study>[_smoke])")
    stu.add_argument("--smoke", action="store_true", help="small grid, short runs (minutes)")
    stu.add_argument("--workers", type=int, default=2,
                     help="local worker processes (default 2, at most 1024)")
    stu.add_argument("--overwrite", action="store_true",
                     help="replace the study output in --out (another study's, or this one's: "
                          "every run computed again); the same study is otherwise continued")
    return p


def format_summary(s: dict) -> str:
    """Human-readable run summary."""
    lines = [
        f"scene: {s['scene']}   coupling: {s['coupling']} ({s.get('mesh_motion')} mesh)   "
        f"particles: {s['particles']}",
        "effects: " + ", ".join(f"{k}={'on' if v else 'off'}" for k, v in s["effects"].items()),
    ]
    if "mesh" in s:
        m = s["mesh"]
        lines.append(
            f"mesh at the end: {m['kind']}, {m['vertices']} vertices, {m['p2_nodes']} P2 nodes, "
            f"{m['triangles']} triangles, {m['dofs']} DOFs, min angle {m['min_angle']:.1f} deg"
        )
    if s.get("adaptive") and s.get("dt_range"):
        lo, hi = s["dt_range"]
        steps = (f"steps: {s['steps']} adaptive (dt {lo:.3g} ... {hi:.3g} s, "
                 f"{s['rejections']} rejected)")
    else:
        steps = f"steps: {s['steps']} (dt = {s['dt']:.3g} s)"
    lines.append(f"{steps} to t = {s['t_end']:.6g} s, remeshes: {s['remeshes']}")
    if "final" in s:
        f = s["final"]
        if s["particles"] == 1:
            lines.append(
                f"particle 0: x = {f['x'][0]:.9g} m, y = {f['y'][0]:.9g} m, "
                f"vx = {f['vx'][0]:.4g} m/s, vy = {f['vy'][0]:.6g} m/s"
            )
        else:
            import numpy as np

            lines.append(f"mean vy = {np.mean(f['vy']):.4g} m/s, lowest y = {min(f['y']):.4g} m")
    wt = s["wall_time"]
    lines.append("wall time: " + ", ".join(f"{k} {v:.3g} s" for k, v in wt.items()))
    for w in s["warnings"]:
        lines.append(f"warning: {w}")
    return "\n".join(lines)


def _check_out(field: str, out) -> None:
    """Fail early, naming ``field``, when the output directory cannot be created or written."""
    from pathlib import Path

    from .io import check_writable

    try:
        check_writable(Path(out) / "summary.json")
    except ValueError as exc:
        raise ValueError(f"{field} = {str(out)!r}: must be a writable directory; {exc}") from None


def main(argv=None) -> int:
    """Entry point; returns the exit code.

    Called with ``argv=None`` (the ``skfem-granular`` command, the whole process), the
    objects that exist are moved out of the garbage collector's reach
    (:func:`gc.freeze`) at the start (the imported modules, which live to the end
    anyway: the collections during the run then skip them, ~0.05 s less) and again
    at the end (the interpreter's last collection at exit would otherwise walk
    everything, ~0.4 s once numba's compiler has been set up; every output file is
    closed by then).
    """
    if argv is None:
        gc.freeze()
    code = _main(argv, whole_process=argv is None)
    if argv is None:
        gc.freeze()
    return code


def _main(argv, whole_process: bool = False) -> int:
    """:func:`main` with SIGINT/SIGTERM before and after a run's loop reported in one line
    (the whole process: ignored once the exit status is decided)."""
    from .signals import StopNow, startup_signals

    try:
        with startup_signals(ignore_after=whole_process):
            return _command(argv)
    except StopNow as exc:  # SIGINT/SIGTERM before a run's loop (reading, meshing)
        print(f"skfem-granular: stopped by {exc.name} during start-up (nothing run)",
              file=sys.stderr)
        return exc.exit_status


def _command(argv) -> int:
    try:
        args = _parser().parse_args(argv)
    except _UsageError as exc:
        print(f"skfem-granular: error: {exc} (see skfem-granular --help)", file=sys.stderr)
        return 2
    if args.command == "scenes":
        return _scenes()
    if args.command == "render":
        from .cli_render import run as run_render

        return run_render(args)
    if args.command == "study":
        return _study(args)
    if args.command == "pack":
        from .cli_pack import run as run_pack

        return run_pack(args)
    if args.command == "collapse":
        from .cli_collapse import run as run_collapse

        return run_collapse(args)
    return _run(args)


def _run(args) -> int:
    """``skfem-granular run``: a scene (or a resumed run) to its end."""
    from .scene import Scene
    from .simulation import Simulation

    try:
        if args.resume is not None:
            if (args.scene or args.mesh or args.dt is not None or args.out or args.tol
                    or args.vtu_every is not None or args.checkpoint_every is not None
                    or args.overwrite):
                raise ValueError("--resume DIR takes no scene, --mesh, --dt, --tol, --out, "
                                 "--vtu-every, --checkpoint-every or --overwrite (the "
                                 "checkpoint holds them); only --t-end may change")
            sim = Simulation.resume(args.resume, t_end=args.t_end, budget=_budget(args))
            return _finish_run(sim, args)
        if not args.scene:
            raise ValueError("run: give a scene file (or --resume DIR)")
        scene = Scene.from_toml(_scene_path(args.scene))
        if args.mesh:
            scene = scene.with_mesh(args.mesh)
        if args.mesh_motion:
            scene = replace(scene, mesh_motion=args.mesh_motion)
        if args.t_end is not None or args.dt is not None or args.tol is not None:
            time_kw = {}
            if args.t_end is not None:
                time_kw["t_end"] = args.t_end
            if args.dt is not None:
                time_kw["dt"] = args.dt
            if args.tol is not None:
                time_kw.update(adaptive=True, tol=args.tol)
            scene = replace(scene, time=replace(scene.time, **time_kw))
        if args.vtu_every is not None:
            scene = replace(scene, vtu_every=args.vtu_every)
        if args.checkpoint_every is not None:
            scene = replace(scene, checkpoint_every=args.checkpoint_every)
        out = args.out or scene.output_dir or f"out/{scene.name}"
        _check_out("--out" if args.out else "output.directory", out)
        sim = Simulation(scene, output_dir=out, overwrite=args.overwrite,
                         budget=_budget(args))
    except (ValueError, OSError) as exc:  # OSError: files the scene names (read, output)
        msg = " ".join(str(exc).split())  # always one line
        print(f"skfem-granular: error: {msg}", file=sys.stderr)
        return 2
    return _finish_run(sim, args)


def _budget(args):
    """The run's :class:`~skfem_granular.simulation.Budget` from ``--max-*``."""
    from .simulation import Budget

    kw = {}
    if args.max_steps is not None:
        kw["max_steps"] = args.max_steps
    if args.max_elements is not None:
        kw["max_elements"] = args.max_elements
    if args.max_memory is not None:  # checked in GB, as given (the budget's bound: 1e6 B)
        from ._validate import in_range

        kw["max_memory"] = in_range("--max-memory", args.max_memory, 1e-3, 1e6) * 1e9
    return Budget(**kw)


def _scene_path(arg: str):
    """``arg`` as a path if it exists, else the bundled scene of that name, else ``arg``
    as a path again (so that reading it reports the missing file)."""
    from pathlib import Path

    from .scene import bundled

    path = Path(arg)
    if path.exists():
        return path
    try:
        return bundled(arg)
    except ValueError:
        return path


def _scenes() -> int:
    """``skfem-granular scenes``: the bundled scenes, one line each."""
    from .scene import bundled_scenes, first_comment

    scenes = bundled_scenes()
    width = max(len(n) for n in scenes)
    for name, path in scenes.items():
        print(f"{name:<{width}}  {first_comment(path)}")
    return 0


def _finish_run(sim, args) -> int:
    import signal

    from .simulation import SimulationError

    try:
        result = sim.run(progress=not args.no_progress)
    except SimulationError as exc:
        print(f"skfem-granular: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 1
    except ValueError as exc:  # the folder taken by another run since the start
        print(f"skfem-granular: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    except OSError as exc:  # the lock file could not be written (a full disk, permissions)
        print(f"skfem-granular: error: output: {exc.strerror or exc}"
              + (f": {exc.filename}" if exc.filename else ""), file=sys.stderr)
        return 1
    print(format_summary(result.summary))
    print(f"output: {result.output_dir}/ (flow.pvd, particles.pvd, history.csv, summary.json)")
    stopped = result.summary.get("stopped_by")
    if stopped:
        print(_stopped_line(result), file=sys.stderr)
        return 128 + int(getattr(signal, stopped))
    return 0


def _stopped_line(result) -> str:
    """What a stopped run tells: where it stopped and how to continue."""
    s, out = result.summary, result.output_dir
    where = (f"stopped by {s['stopped_by']}{' at once' if s.get('stopped_at_once') else ''} "
             f"at t = {s['t_end']:.6g} s")
    if out is None:
        return where
    if (out / "checkpoint.npz").exists():
        return f"{where}; continue with: skfem-granular run --resume {out}"
    return f"{where}; no checkpoint was written yet, so it cannot be resumed"


def _study(args) -> int:
    """``skfem-granular study``: run or resume a study, print the table's path and orders."""
    from . import studies
    from .studies.plots import require_matplotlib

    out = args.out or f"out/study_{args.study.replace('-', '_')}{'_smoke' if args.smoke else ''}"
    try:
        from ._validate import MAX_WORKERS, in_range

        in_range("--workers", args.workers, 1, MAX_WORKERS, integer=True)
        require_matplotlib()  # before any run and before the output folder is made
        _check_out("--out", out)
        res = studies.run_study(args.study, out, smoke=args.smoke, workers=args.workers,
                                overwrite=args.overwrite, log=lambda m: print(m, flush=True))
    except (ValueError, OSError, ImportError) as exc:  # ImportError: matplotlib (plot extra)
        print(f"skfem-granular: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    print(f"{len(res.computed)} runs computed, {len(res.rows) - len(res.computed)} reused, "
          f"{len(res.failed)} failed")
    for key, msg in res.failed.items():
        print(f"failed: {key}: {msg}")
    orders = studies.orders(res.rows)
    print("fitted orders (h-equivalent): " + ", ".join(f"{k} {v:.2f}" for k, v in orders.items()))
    print("wrote " + ", ".join(str(f) for f in res.files))
    return 1 if res.failed else 0


if __name__ == "__main__":
    sys.exit(main())
