"""Collapse measurements over a whole run: from its history (in memory or ``history.csv``).

:func:`collapse_series` turns the per-step positions and velocities of the grains
into the time series collapse experiments report; :func:`history_columns` reads
them back from a run's ``history.csv`` (wide layout: ``x_0, x_1, ...``).
"""

from __future__ import annotations

import numpy as np

from ..io import read_csv
from ..packing import Packing
from .measures import (
    flowing_solid_fraction,
    front_speed,
    front_vertex,
    grain_outlines,
    height_at,
    kinetic_energies,
    local_outlines,
    masses,
)

__all__ = ["COLUMNS", "collapse_series", "history_columns", "initial_column"]

#: the per-grain columns the measurements need
COLUMNS = ("x", "y", "angle", "vx", "vy", "omega")


def history_columns(path) -> dict[str, np.ndarray]:
    """``{"t": (T,), "x": (T, N), ...}`` from a run's ``history.csv``."""
    d = read_csv(path)
    n = sum(1 for k in d if k.startswith("x_"))
    out = {"t": d["t"]}
    for c in COLUMNS:
        out[c] = np.column_stack([d[f"{c}_{k}"] for k in range(n)])
    return out


def initial_column(packing: Packing, domain) -> dict[str, np.ndarray]:
    """The row of the column at rest at ``t = 0`` (placed in ``domain`` as the scene does)."""
    _, C = local_outlines(packing)
    n = packing.n
    return {"t": np.zeros(1), "x": C[0][None] + domain[0], "y": C[1][None] + domain[1],
            **{c: np.zeros((1, n)) for c in ("angle", "vx", "vy", "omega")}}


def collapse_series(columns, packing: Packing, domain, gravity: float = 9.81,
                    flowing: float = 0.01) -> dict:
    """Run-out, gate height and kinetic energies at every row of ``columns``.

    Parameters
    ----------
    columns : dict or History
        ``t`` ``(T,)`` and ``x, y, angle, vx, vy, omega`` ``(T, N)`` (a
        :class:`~skfem_granular.io.History` or :func:`history_columns`).
    packing : Packing
        The column the run started from (outlines, mass, ``L0``, ``H0``).
    domain : (x0, y0, x1, y1)
        The tank (the column stands on its floor against its left wall).
    flowing : float
        A grain flows when faster than ``flowing * sqrt(g H0)``.

    Returns
    -------
    dict of arrays
        ``t``, ``t_over_tau`` (``t / sqrt(H0/g)``), ``front`` (m, from the left wall),
        ``runout`` (``(L - L0) / L0``), ``gate_height`` (``h`` at the gate over ``H0``),
        ``E_x``, ``E_y``, ``E_rot`` (J/m), ``froude`` (``U_f / sqrt(g H0)``, ``U_f`` the
        horizontal speed of the grain material at the front, :func:`front_speed`: unlike
        the differences of ``L``, it does not jump where the front passes to another
        grain), ``flowing_fraction`` (:func:`flowing_solid_fraction`; NaN with fewer
        than three flowing grains).
    """
    get = columns.get if isinstance(columns, dict) else lambda c: getattr(columns, c)
    local, _ = local_outlines(packing)
    m, J = masses(packing)
    x0, y0 = domain[0], domain[1]
    L0, H0 = packing.width, packing.height
    t = np.asarray(get("t"), dtype=float)
    X, Y, A, VX, VY, W = (np.asarray(get(c), dtype=float) for c in COLUMNS)
    v_flow = flowing * np.sqrt(gravity * H0)
    rows = []
    for i in range(t.size):
        P = [Q - np.array([[x0], [y0]]) for Q in grain_outlines(local, X[i], Y[i], A[i])]
        front, k, j = front_vertex(P)
        U_f = front_speed(P, k, j, np.vstack([X[i] - x0, Y[i] - y0]),
                          np.vstack([VX[i], VY[i]]), W[i])
        rows.append((front, height_at(P, L0, packing.d_max) / H0,
                     *kinetic_energies(m, J, np.vstack([VX[i], VY[i]]), W[i]),
                     flowing_solid_fraction(P, np.hypot(VX[i], VY[i]), v_flow),
                     U_f / np.sqrt(gravity * H0)))
    R = np.array(rows).reshape(-1, 7)
    Fr = R[:, 6]
    return {"t": t, "t_over_tau": t / np.sqrt(H0 / gravity), "front": R[:, 0],
            "runout": (R[:, 0] - L0) / L0, "gate_height": R[:, 1], "E_x": R[:, 2],
            "E_y": R[:, 3], "E_rot": R[:, 4], "froude": Fr, "flowing_fraction": R[:, 5]}
