"""Canonical test geometries built directly with ``triangle``.

The fluid tests must not depend on the ``meshing`` package (they test the
fluid core alone), so the few meshes they need are made here: an annulus
between two regular polygons, a rectangle with an optional polygonal hole.
:func:`fail_midway` makes a library's writer fail halfway through a file.
"""

from __future__ import annotations

import functools

import numpy as np
import triangle
from skfem import MeshTri


def regular_polygon(n: int, radius: float, center=(0.0, 0.0), angle: float = 0.0) -> np.ndarray:
    """Counter-clockwise vertices ``(2, n)`` of a regular polygon."""
    phi = angle + 2 * np.pi * np.arange(n) / n
    return np.array([center[0] + radius * np.cos(phi), center[1] + radius * np.sin(phi)])


def _loop(start: int, n: int) -> np.ndarray:
    i = np.arange(n)
    return np.stack([start + i, start + (i + 1) % n], axis=1)


def _mesh(vertices, segments, markers, holes, max_area, names):
    data = dict(vertices=vertices, segments=segments, segment_markers=markers[:, None])
    if holes:
        data["holes"] = np.array(holes)
    out = triangle.triangulate(data, f"pq30a{max_area:.12f}")
    mesh = MeshTri(out["vertices"].T.copy(), out["triangles"].T.copy())
    # facets to segment markers via vertex pairs of the output segments
    seg = np.sort(out["segments"], axis=1)
    mark = out["segment_markers"].ravel()
    f = np.sort(mesh.facets.T, axis=1)
    key = {tuple(s): m for s, m in zip(seg.tolist(), mark.tolist(), strict=True)}
    fm = np.array([key.get(tuple(e), 0) for e in f.tolist()])
    return mesh.with_boundaries({nm: np.flatnonzero(fm == m) for m, nm in names.items()})


def annulus(a: float, b: float, n_inner: int, n_outer: int, max_area: float) -> MeshTri:
    """Mesh between a regular ``n_inner``-gon of radius ``a`` and an ``n_outer``-gon, radius ``b``.

    Boundaries: ``"inner"`` and ``"outer"``.
    """
    vin = regular_polygon(n_inner, a)
    vout = regular_polygon(n_outer, b)
    V = np.hstack([vout, vin]).T
    S = np.vstack([_loop(0, n_outer), _loop(n_outer, n_inner)])
    M = np.concatenate([np.full(n_outer, 1), np.full(n_inner, 2)])
    return _mesh(V, S, M, [(0.0, 0.0)], max_area, {1: "outer", 2: "inner"})


def box(x0, y0, x1, y1, max_area, hole=None) -> MeshTri:
    """Rectangle with boundaries left/right/bottom/top (and ``"particle0"`` around ``hole``).

    ``hole`` is a ``(2, n)`` counter-clockwise polygon inside the box.
    """
    V = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=float)
    S = _loop(0, 4)
    M = np.array([3, 2, 4, 1])  # bottom, right, top, left
    holes = []
    if hole is not None:
        n = hole.shape[1]
        V = np.vstack([V, hole.T])
        S = np.vstack([S, _loop(4, n)])
        M = np.concatenate([M, np.full(n, 5)])
        holes = [tuple(hole.mean(axis=1))]
    mesh = _mesh(
        V, S, M, holes, max_area, {1: "left", 2: "right", 3: "bottom", 4: "top", 5: "particle0"}
    )
    b = mesh.boundaries
    walls = np.concatenate([b[k] for k in ("left", "right", "bottom", "top")])
    return mesh.with_boundaries({"wall": walls})


@functools.cache
def column_packing(state: str = "dense"):
    """The canonical small column: 30 near-disks (d_max / d_min = 1.8), aspect 0.8, seed 3,
    soft contacts (E = 2e5 N/m), solid fraction one d_max from the edges (cached)."""
    from skfem_granular.packing import prepare_column

    return prepare_column(30, 0.8, state, seed=3, E=2e5, margin=1.0)


def fail_midway(monkeypatch, owner, name: str, where, data: bytes = b"partial bytes") -> list:
    """Make ``owner.name`` write ``data`` to the file ``where(*args)`` names, then fail as on a
    full disk (``OSError`` ENOSPC). Returns the files it wrote to (one per call)."""
    import errno
    import os
    from pathlib import Path

    written = []

    def failing(*args, **kwargs):
        path = Path(where(*args))
        with open(path, "wb") as fh:
            fh.write(data)
        written.append(path)
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))

    monkeypatch.setattr(owner, name, failing)
    return written


def partial_names(directory) -> list[str]:
    """The names in ``directory`` of temporary files an atomic writer leaves behind."""
    from pathlib import Path

    return sorted(p.name for p in Path(directory).iterdir() if p.name.startswith(".partial-"))


def only_error_line(capsys) -> str:
    """The one line a command wrote to stderr (no traceback), from pytest's ``capsys``."""
    cap = capsys.readouterr()
    lines = cap.err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in cap.err, cap.err
    return lines[0]


def released_cylinder(a: float = 1e-3, b: float = 2e-3, n_seg: int = 64):
    """A cylinder of radius ``a`` (``n_seg``-gon, boundary ``particle0``) at rest inside a
    fixed concentric one of radius ``b`` (``wall``): ``(TaylorHood space, the inner
    polygon's area)``, the added-mass geometry of docs/validation.md case 7."""
    from skfem_granular.fluid import TaylorHood

    mesh = annulus(a, b, n_seg, 2 * n_seg, (a * 0.04) ** 2)
    mesh = mesh.with_boundaries(
        {"particle0": mesh.boundaries["inner"], "wall": mesh.boundaries["outer"]}
    )
    return TaylorHood(mesh), 0.5 * n_seg * a**2 * np.sin(2 * np.pi / n_seg)


def resumed_between_checkpoints(scene, tmp_path, k: int):
    """``(uninterrupted history, resumed history)``: ``scene`` run through, and run again
    with a checkpoint written after step ``k`` (where the run writes none, as SIGTERM
    does) and resumed from it."""
    from contextlib import closing

    from skfem_granular.simulation import Simulation, checkpoint

    ref = Simulation(scene, output_dir=tmp_path / "ref").run(progress=False).history
    sim = Simulation(scene, output_dir=tmp_path / "part")
    with closing(sim.evolve()) as steps:
        for i, _ in enumerate(steps, start=1):
            if i == k:
                checkpoint.save(sim, i, None)
                break
    return ref, Simulation.resume(tmp_path / "part").run(progress=False).history


def coupled_run_through(monkeypatch, size_name: str, steps: int = 20):
    """The paper's particle over ``steps`` coupled steps with ``linsolve.<size_name>`` (the
    size from which ``solver="auto"`` picks that solver) lowered to 0, and the same run on
    the default solver: ``(history, reference history, solver name)``."""
    from dataclasses import replace

    from skfem_granular.fluid import linsolve
    from skfem_granular.scene import Scene
    from skfem_granular.simulation import Simulation

    sc = replace(Scene.bundled("single_particle"), output_dir=None)
    sc = replace(sc, time=replace(sc.time, t_end=steps * sc.time.dt))
    ref = Simulation(sc).run(progress=False).history
    monkeypatch.setattr(linsolve, size_name, 0)
    sim = Simulation(sc)
    return sim.run(progress=False).history, ref, sim.stepper.coupling.solver.name
