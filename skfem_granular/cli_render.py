"""``skfem-granular render``: a picture (PNG) or an animation (GIF, MP4) of a run's output.

Options and output paths are checked before a frame is read (exit 2, one line); a write
that fails midway exits 1 and leaves an earlier file as it was.
"""

from __future__ import annotations

import sys

from ._validate import in_range
from .io import check_output_file


def add_parser(sub) -> None:
    """Add ``render`` to the subcommands ``sub`` of the main parser."""
    ren = sub.add_parser("render", help="picture (PNG) or animation (GIF/MP4) of a run's output")
    ren.add_argument("out", help="output directory of a run (with flow.pvd, particles.pvd)")
    ren.add_argument("--field", default="speed", choices=["speed", "pressure", "vorticity", "mesh"])
    ren.add_argument("--vectors", choices=["glyphs", "streamlines"], help="overlay")
    ren.add_argument("--frame", type=int, default=-1, help="frame index for --png (default last)")
    ren.add_argument("--png", help="write one frame to this PNG")
    ren.add_argument("--animation", help="write all frames to this .gif (or .mp4)")
    ren.add_argument("--every", type=int, default=1,
                     help="--animation: every N-th frame (default 1)")
    ren.add_argument("--fps", type=float, default=10.0,
                     help="--animation: frames per second (default 10)")


def run(args) -> int:
    """``skfem-granular render``: options and output paths checked before anything is read."""
    from pathlib import Path

    from . import viz

    out = Path(args.out)
    try:
        viz.check_fps(args.fps, "--fps")
        in_range("--every", args.every, 1, integer=True)
        if not args.png and not args.animation:
            raise ValueError("render: give --png PATH and/or --animation PATH")
        for option, path, suffixes in (("--png", args.png, (".png",)),
                                       ("--animation", args.animation, (".gif", ".mp4"))):
            if path:
                check_output_file(option, path, suffixes)
        if not (out / "flow.pvd").exists():
            raise ValueError(f"out = {str(out)!r}: no flow.pvd there (run a fluid scene first)")
        frames = viz.read_pvd(out / "flow.pvd")
        parts = viz.read_pvd(out / "particles.pvd") if (out / "particles.pvd").exists() else []
        if args.png:
            if not -len(frames) <= args.frame < len(frames):
                raise ValueError(f"--frame = {args.frame}: must be in [{-len(frames)}, "
                                 f"{len(frames) - 1}]")
            t, f = frames[args.frame]
            p = parts[args.frame][1] if len(parts) == len(frames) else None
            viz.render_frame(f, p, args.png, field=args.field, vectors=args.vectors, time=t)
            print(f"wrote {args.png}")
        if args.animation:
            viz.render_series(out, args.animation, field=args.field, vectors=args.vectors,
                              every=args.every, fps=args.fps)
            print(f"wrote {args.animation}")
    except (ValueError, ImportError) as exc:
        print(f"skfem-granular: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    except OSError as exc:  # reading a frame or writing the picture failed (a full disk)
        print(f"skfem-granular: error: render: {exc.strerror or exc}"
              + (f": {exc.filename}" if exc.filename else "")
              + " (a file written before keeps its content)", file=sys.stderr)
        return 1
    return 0
