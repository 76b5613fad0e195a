"""Figures of the meshing package, after the paper's Figs. 5, 6, 7 and 13.

Usage: ``python scripts/mesh_figures.py [--outdir docs/figures]``. Writes
``mesh_fig5_graded_circle.png`` (graded mesh around a circular particle),
``mesh_fig6_cleanup.png`` (truncated circles before and after merging and
relaxation), ``mesh_fig7_fine_vs_graded.png`` (the 3 x 11 mm box, equidistant
vs graded, same 24-segment outline) and ``mesh_fig13_group_sector.png``
(a particle group on the bottom wall: fine sector, graded outside).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import meshing  # noqa: E402
from meshing import cleanup, geometry, graded, pslg  # noqa: E402

BOX = (0.0, 0.0, 3e-3, 11e-3)


def regular(n, r=0.5e-3, c=(1.5e-3, 5.5e-3), rot=0.0):
    th = rot + 2.0 * np.pi * np.arange(n) / n
    return np.vstack([c[0] + r * np.cos(th), c[1] + r * np.sin(th)])


def title(ax, mesh, text):
    s = meshing.mesh_stats(mesh)
    ax.set_title(f"{text}\n{s.n_vertices} vertices, {s.n_p2_nodes} P2 nodes\n"
                 f"min angle {s.min_angle:.0f} deg, max R/2r {s.max_aspect:.2f}", fontsize=9)


def fig5(out: Path) -> None:
    disk = regular(24, c=(0.0, 0.0))
    mesh = meshing.graded_mesh((-6e-3, -6e-3, 6e-3, 6e-3), [disk], relax_rounds=0)
    fig, ax = plt.subplots(figsize=(6, 6))
    meshing.plot_mesh(mesh, ax=ax, legend=False)
    ring = graded.rings(disk, None, 6e-3)
    for r in ring.radii:
        ax.add_patch(plt.Circle((0, 0), r, fill=False, lw=0.4, ls=":", color="tab:blue"))
    title(ax, mesh, f"Graded mesh around a 24-gon (Eq. 4, sigma = {ring.sigma:.3f}), "
                    "no relaxation")
    ax.set_xlim(-6e-3, 6e-3)
    ax.set_ylim(-6e-3, 6e-3)
    fig.savefig(out / "mesh_fig5_graded_circle.png", dpi=150, bbox_inches="tight")
    plt.close(fig)


def fig6(out: Path) -> None:
    disk = regular(24, c=(0.8e-3, 2.5e-3))
    D, names = geometry.as_domain(BOX)
    ring = graded.rings(disk, None, 12e-3)
    x = graded.ring_nodes(disk, ring)
    keep = geometry.edge_distance(D, x)[0] > 0.0
    raw_wall = np.hstack([D])
    raw = pslg.Layout(D, names, [disk], raw_wall, np.arange(4), x[:, keep])
    raw_free = raw.free[:, ~cleanup.near_particles([disk], raw.free,
                                                   np.full(raw.free.shape[1], 1e-5))]
    raw = pslg.Layout(D, names, [disk], raw_wall, np.arange(4), raw_free)
    tri = pslg.triangulate(raw)
    final = meshing.graded_mesh(BOX, [disk])
    fig, axs = plt.subplots(1, 2, figsize=(7, 5))
    axs[0].triplot(tri.points[0], tri.points[1], tri.t.T, lw=0.4, color="0.4")
    axs[0].set_aspect("equal")
    axs[0].set_title("circles truncated at the box only", fontsize=9)
    meshing.plot_mesh(final, ax=axs[1], legend=False)
    title(axs[1], final, "projected, merged, relaxed")
    for ax in axs:
        ax.set_xlim(0, 3e-3)
        ax.set_ylim(0, 5e-3)
    fig.savefig(out / "mesh_fig6_cleanup.png", dpi=150, bbox_inches="tight")
    plt.close(fig)


def fig7(out: Path) -> None:
    disk = regular(24)
    fine = meshing.uniform_mesh(BOX, [disk])
    grad = meshing.graded_mesh(BOX, [disk])
    fig, axs = plt.subplots(1, 2, figsize=(7, 10))
    meshing.plot_mesh(fine, ax=axs[0], lw=0.2, legend=False)
    title(axs[0], fine, "equidistant (fine)")
    meshing.plot_mesh(grad, ax=axs[1], lw=0.4)
    title(axs[1], grad, "graded")
    fig.savefig(out / "mesh_fig7_fine_vs_graded.png", dpi=150, bbox_inches="tight")
    plt.close(fig)


def fig13(out: Path) -> None:
    rng = np.random.default_rng(3)
    parts = [regular(12, 0.2e-3, (5e-3 + (i - 3) * 0.5e-3 + 0.25e-3 * (j % 2),
                                  0.3e-3 + j * 0.45e-3), rng.uniform(0, 1))
             for j in range(4) for i in range(7 - (j % 2))]
    mesh = meshing.group_mesh((0.0, 0.0, 10e-3, 12e-3), parts, center=(5.1e-3, 0.0))
    fig, ax = plt.subplots(figsize=(7, 8))
    meshing.plot_mesh(mesh, ax=ax, lw=0.3, legend=False)
    f2t = mesh.f2t
    fine = np.zeros(mesh.t.shape[1], dtype=bool)
    fine[mesh.subdomains["fine"]] = True
    inner = f2t[1] >= 0
    trans = np.flatnonzero(inner & (fine[f2t[0]] != fine[np.maximum(f2t[1], 0)]))
    for f in trans:
        ax.plot(*mesh.p[:, mesh.facets[:, f]], color="tab:blue", lw=1.5)
    title(ax, mesh, f"{len(parts)} particles: fine sector, transition (blue), graded outside")
    fig.savefig(out / "mesh_fig13_group_sector.png", dpi=150, bbox_inches="tight")
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--outdir", default=str(Path(__file__).resolve().parents[1] / "docs"
                                            / "figures"))
    args = ap.parse_args(argv)
    out = Path(args.outdir)
    out.mkdir(parents=True, exist_ok=True)
    for f in (fig5, fig6, fig7, fig13):
        f(out)
        print(f"{f.__name__} written to {out}")


if __name__ == "__main__":
    main()
