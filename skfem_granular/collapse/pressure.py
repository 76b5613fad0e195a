"""Excess pore pressure along horizontal lines, from a live flow or a saved frame.

Convention. The solver works with the *dynamic* pressure ``p``: the hydrostatic
part ``rho_f g (y_ref - y)`` is removed from the equations (the grains feel
buoyancy-reduced gravity), so ``p`` is the fluid pressure minus hydrostatic, up to
the constant that fixes pressure in a closed tank (the solver returns zero mean over
the fluid). The excess pore pressure reported here is ``p(x) - p(x_ref)``: the
dynamic pressure relative to a reference point in still fluid far from the column
(default: near the tank's top right corner), i.e. the total pressure minus the
hydrostatic pressure of a fluid column that has the reference point's pressure at
its height. Positive under a column that contracts (a loose packing pushes fluid
out), negative under one that dilates (a dense packing sucks fluid in).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["excess_pressure", "flow_pressure", "frame_pressure", "line_points",
           "reference_point"]


def line_points(x0: float, x1: float, y: float, n: int = 200) -> np.ndarray:
    """``(2, n)`` points evenly along ``y = const`` from ``x0`` to ``x1``."""
    return np.vstack([np.linspace(x0, x1, n), np.full(n, float(y))])


def reference_point(domain, margin: float) -> np.ndarray:
    """``(2, 1)`` point ``margin`` inside the top right corner of ``domain``."""
    x0, y0, x1, y1 = domain
    return np.array([[x1 - margin], [y1 - margin]])


def _interpolate(points_xy, triangles, values, P) -> np.ndarray:
    """P1 interpolation on a triangulation; ``nan`` outside it (inside a grain's core)."""
    from matplotlib.tri import LinearTriInterpolator, Triangulation

    T = Triangulation(points_xy[0], points_xy[1], triangles)
    f = LinearTriInterpolator(T, values)
    return np.ma.filled(f(P[0], P[1]).astype(float), np.nan)


def frame_pressure(path, points) -> np.ndarray:
    """Pressure at ``points`` (2, n) from a saved VTU flow frame (P1: linear in triangles).

    Points outside the fluid (inside a grain's core) give ``nan``.
    """
    import meshio

    m = meshio.read(Path(path))
    tri = m.cells_dict["triangle6"][:, :3]
    return _interpolate(m.points[:, :2].T, tri, m.point_data["pressure"],
                        np.asarray(points, dtype=float))


def flow_pressure(flow, points) -> np.ndarray:
    """Pressure at ``points`` (2, n) of a live flow; ``nan`` inside a grain's core."""
    mesh = flow.mesh
    return _interpolate(mesh.p, mesh.t.T, flow.pressure(mesh.p), np.asarray(points, float))


def excess_pressure(source, points, ref) -> np.ndarray:
    """Excess pore pressure ``p(points) - p(ref)`` (see the module notes).

    Parameters
    ----------
    source : Flow or str or Path
        A live :class:`~skfem_granular.fluid.Flow` (``sim.stepper.flow()``) or a saved
        ``flow_*.vtu`` frame.
    points : (2, n) array
    ref : (2, 1) array
        The reference point in still fluid (:func:`reference_point`).
    """
    P = np.hstack([np.asarray(points, dtype=float), np.asarray(ref, dtype=float)])
    p = frame_pressure(source, P) if isinstance(source, (str, Path)) else flow_pressure(source, P)
    return p[:-1] - p[-1]
