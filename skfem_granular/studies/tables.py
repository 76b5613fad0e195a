"""The tables of a study: ``table.csv`` (every column) and ``table.md`` (the readable subset)."""

from __future__ import annotations

import math
from pathlib import Path

from ..io import atomic_write, write_text
from .analysis import orders
from .definitions import COLUMNS


def _fmt(v, full=False):
    if v is None:
        return ""
    if isinstance(v, float):
        return "nan" if math.isnan(v) else (repr(v) if full else f"{v:.4g}")
    return str(v)


def write_tables(rows, out_dir, study, smoke) -> list[Path]:
    """``table.csv`` (all columns) and ``table.md`` (the readable subset) with fitted orders,
    each written atomically (a failure leaves an earlier table as it was)."""
    import csv

    out_dir = Path(out_dir)

    def write_csv(tmp) -> None:
        with open(tmp, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=COLUMNS)
            w.writeheader()
            w.writerows({c: _fmt(r[c], full=True) for c in COLUMNS} for r in rows)

    atomic_write(out_dir / "table.csv", write_csv)
    cols: tuple[str, ...] = (
        "family",
        "n_sides" if study == "faxen" else "h",
        "delta_l",
        "sigma",
        "dt",
        "seed",
        "vertices",
        "p2_nodes",
        "dofs",
        "wall_time",
        "wall_solve",
        "peak_rss_mb",
        "value",
        "error",
        "error_curve",
        "rounding_mirror",
        "rounding_renumber",
        "rounding_field",
    )
    drop = ("dt", "error_curve", "h", "delta_l") if study == "faxen" else ("rounding_field",)
    cols = tuple(c for c in cols if c not in drop)
    refs = sorted({r["reference"] for r in rows if r["reference"]})
    lines = [
        f"# {study} study{' (smoke)' if smoke else ''}",
        "",
        f"quantity: {rows[0]['quantity'] if rows else ''}; reference: " + "; ".join(refs),
        "error: relative to the reference; error_curve: max |v_y(t) - v_y,ref(t)| / "
        "max |v_y,ref|; rounding_mirror: cross-stream/stream ratio on mirror-symmetric "
        "meshes (rounding alone); rounding_renumber: relative spread over node "
        "renumberings (single particle: of the whole v_y curve); rounding_field: "
        "the same for the pressure at 74 fixed points; wall times in s; "
        "peak_rss_mb: peak resident memory of the worker process.",
        "",
        "| " + " | ".join(cols) + " |",
        "|" + "---|" * len(cols),
    ]
    lines += ["| " + " | ".join(_fmt(r[c]) for c in cols) + " |" for r in rows]
    lines += [
        "",
        "Fitted orders (h-equivalent, err ~ DOFs^(-p/2)): "
        + ", ".join(f"{k} {v:.2f}" for k, v in orders(rows).items()),
    ]
    write_text(out_dir / "table.md", "\n".join(lines) + "\n")
    return [out_dir / "table.csv", out_dir / "table.md"]
