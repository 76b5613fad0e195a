"""``skfem-granular pack``: a dense or loose column of grains prepared with the DEM alone.

``skfem-granular pack N --out FILE.npz [--aspect A] [--state dense|loose] [--shape S]
[--seed K] [--size-ratio R] [--d-mean D] [--margin M] [--scene FILE.toml [--dry]]``
prepares a column of N grains (:func:`skfem_granular.packing.prepare_column`), saves it
and prints its solid fraction; ``--scene`` also writes a collapse scene using it. Every
number and output file is checked before the column is prepared (exit 2, one line).
"""

from __future__ import annotations

import sys

from ._validate import MAX_SEED, in_range
from .io import check_output_file


def add_parser(sub) -> None:
    """Add ``pack`` to the subcommands ``sub`` of the main parser."""
    pk = sub.add_parser("pack", help="prepare a dense or loose column of grains (DEM only)")
    pk.add_argument("n", type=int, help="number of grains")
    pk.add_argument("--out", required=True, help="the packing file (.npz) to write")
    pk.add_argument("--aspect", type=float, default=0.8, help="H0 / L0 (default 0.8)")
    pk.add_argument("--state", default="dense", help="dense or loose (default dense)")
    pk.add_argument("--shape", default="ngon", help="ngon, hexagon or irregular")
    pk.add_argument("--seed", type=int, default=0)
    pk.add_argument("--size-ratio", type=float, default=1.8, help="d_max / d_min")
    pk.add_argument("--d-mean", type=float, default=1e-3, help="mean diameter (m)")
    pk.add_argument("--margin", type=float, default=None,
                    help="solid fraction measured this many d_max from the edges "
                         "(default 2, and 0.5 for columns of fewer than 100 grains)")
    pk.add_argument("--scene", help="also write a collapse scene (TOML) using the packing")
    pk.add_argument("--dry", action="store_true", help="the scene without fluid")


def _pack_checks(args) -> None:
    """``pack``'s numbers and output files, refused in one line naming the option, before the
    column is prepared."""
    from .scene.parse import MAX_PARTICLES

    in_range("n", args.n, 1, MAX_PARTICLES, integer=True)
    in_range("--aspect", args.aspect, 0.05, 20)
    in_range("--seed", args.seed, 0, MAX_SEED, integer=True)
    in_range("--size-ratio", args.size_ratio, 1, 4)
    in_range("--d-mean", args.d_mean, 1e-5, 0.1)
    if args.margin is not None:
        in_range("--margin", args.margin, 0, 20)
    check_output_file("--out", _npz(args.out), (".npz",))
    if args.scene:
        check_output_file("--scene", args.scene, None)


def _npz(path):
    """``path`` as :meth:`~skfem_granular.packing.Packing.save` writes it (``.npz`` added)."""
    return path if str(path).endswith(".npz") else f"{path}.npz"


def run(args) -> int:
    """``skfem-granular pack``: prepare, save, report (and write a scene)."""
    from pathlib import Path

    from .collapse import column_toml
    from .io import atomic_write
    from .packing import prepare_column

    try:
        _pack_checks(args)
        p = prepare_column(args.n, args.aspect, args.state, shape=args.shape, seed=args.seed,
                           size_ratio=args.size_ratio, d_mean=args.d_mean,
                           margin=args.margin)
        path = p.save(args.out)
        if args.scene:
            text = column_toml(p, Path(path).resolve(), fluid=not args.dry)
            atomic_write(args.scene, lambda tmp: Path(tmp).write_text(text))
    except (ValueError, OSError, RuntimeError) as exc:
        print(f"skfem-granular: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    print(f"{p.n} grains, {p.state}: solid fraction {p.solid_fraction:.4f}, L0 = {p.width:.6g} m,"
          f" H0 = {p.height:.6g} m (a = {p.aspect:.3g}), settled in {p.settle_time:.3g} s "
          f"({p.wall_time:.1f} s wall) -> {path}")
    return 0
