"""The unsteady DFG cylinder benchmarks 2D-2 and 2D-3 (Schaefer & Turek 1996).

A channel ``[0, 2.2] x [0, 0.41]`` with a cylinder of radius 0.05 at ``(0.2, 0.2)``,
``rho = 1``, ``nu = 1e-3``; parabolic inflow ``u = (4 U(t) y (H - y) / H^2, 0)`` on the
left, no slip on the walls and the cylinder, do-nothing outflow on the right
(``nu grad(u) n - p n = 0``, the Laplacian form of the viscous term,
``viscous="laplace"``), fluid at rest at ``t = 0``.

- **2D-2** (Re 100, ``U = 1.5``): periodic vortex shedding. Schaefer & Turek give
  intervals for the largest drag and lift coefficients over a period and the
  Strouhal number ``St = D f / U_mean`` of the lift: ``c_D,max`` in [3.22, 3.24],
  ``c_L,max`` in [0.99, 1.01], ``St`` in [0.295, 0.305]. The inflow is ramped up
  smoothly over ``ramp`` time units, ``U = 1.5 (1 - cos(pi t / ramp)) / 2``; the
  quantities are taken over the last periods of the run.
- **2D-3** (``U(t) = 1.5 sin(pi t / 8)``, ``t`` in [0, 8]): John (2004) computed
  ``c_D,max = 2.950921575`` at ``t = 3.93625``, ``c_L,max = 0.47795`` at
  ``t = 5.693125`` and ``p(0.15, 0.2) - p(0.25, 0.2) = -0.1116`` at ``t = 8``.

Coefficients ``c = 2 F / (rho U_mean^2 D)`` with ``U_mean = 2 * 1.5 / 3 = 1`` and
``D = 0.1``; ``F`` is the consistent (momentum-residual) force of the fluid on the
cylinder, which includes the fluid's inertia. The cylinder is a regular polygon with
vertices on the circle (one at ``(0.25, 0.2)``), so straight-sided P2 triangles
represent it exactly and the pressure probes are mesh vertices. The library's own
graded mesher (:func:`meshing.field_mesh`) grades the elements from the polygon's edge
length outwards and caps them at ``h_max`` (to ``wake_end``) and ``h_outlet``
(at the outlet). Time stepping is the library's variable-step BDF2
(:func:`~skfem_granular.fluid.evolve`), with fixed steps or adaptive ones.

References
----------
M. Schaefer, S. Turek: Benchmark computations of laminar flow around a cylinder. In
E. H. Hirschel (ed.), Flow Simulation with High-Performance Computers II, Notes on
Numerical Fluid Mechanics 52, Vieweg 1996, 547-566.

V. John: Reference values for drag and lift of a two-dimensional time-dependent flow
around a cylinder. Int. J. Numer. Meth. Fluids 44 (2004) 777-788, doi:10.1002/fld.679.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .._validate import in_range
from ..fluid import Flow, Fluid
from ..fluid.points import PointLocator, evaluation_matrix
from ..fluid.unsteady import evolve

__all__ = ["DFG2D2_INTERVALS", "DFG2D3_REFERENCE", "DFGSeries", "channel_mesh", "dfg2d2_summary",
           "dfg2d3_summary", "inflow_speed", "lift_period", "peak", "run_dfg"]

LENGTH, HEIGHT = 2.2, 0.41
CENTER, RADIUS = (0.2, 0.2), 0.05
DENSITY, VISCOSITY = 1.0, 1e-3
U_MAX = 1.5
U_MEAN, DIAMETER = 2.0 * U_MAX / 3.0, 2.0 * RADIUS
#: Pressure probes, columns ``(0.15, 0.2)`` and ``(0.25, 0.2)``: ``dp = p[0] - p[1]``.
PROBES = np.array([[0.15, 0.25], [0.2, 0.2]])
INLET, OUTLET, CYLINDER, WALLS = "left", "right", "particle0", ("bottom", "top")
CASES = ("2D-2", "2D-3")
#: Corrector iterations per step before the step is halved (the library's default is 12;
#: a halved fixed step stays halved, which would blur a step-size study).
MAX_ITERATIONS = 20
#: Point location tolerance (element sizes) when a warm start is interpolated to a mesh
#: with another cylinder polygon: its nodes may lie up to the polygons' sagitta
#: difference (6e-5 for a 64-gon) inside the old polygon.
START_TOL = 0.1
#: Duration of 2D-3 (the inflow is half a sine period).
T_END_2D3 = 8.0

#: John (2004), Table 4 / eqs. 8-10: the reference values of 2D-3.
DFG2D3_REFERENCE = {"cd_max": 2.950921575, "t_cd_max": 3.93625, "cl_max": 0.47795,
                    "t_cl_max": 5.693125, "dp_end": -0.1116}
#: Schaefer & Turek (1996): the intervals of 2D-2.
DFG2D2_INTERVALS = {"cd_max": (3.22, 3.24), "cl_max": (0.99, 1.01), "strouhal": (0.295, 0.305)}


def channel_mesh(sides: int = 64, h_max: float = 0.025, *, h_outlet: float | None = None,
                 wake_end: float = 1.0, sigma: float | None = None):
    """The DFG channel with a regular ``sides``-gon for the cylinder, graded.

    Parameters
    ----------
    sides : int
        Vertices of the cylinder polygon (on the circle), an even integer in
        [16, 2048]; the polygon's edge ``2 pi r / sides`` is the finest element size.
    h_max : float
        Largest element size up to ``x = wake_end``, in [0.002, 0.2].
    h_outlet : float, optional
        Largest element size at the outlet (linear from ``wake_end`` on), in
        [h_max, 0.2]; default ``h_max``.
    wake_end : float
        Where the growth towards ``h_outlet`` starts, in [0.3, 2.2].
    sigma : float, optional
        Element size growth per layer away from the cylinder, in (1, 1.6]
        (default :data:`meshing.field.FIELD_SIGMA` = 1.2).

    Returns
    -------
    skfem.MeshTri
        Boundaries ``"left"`` (inflow), ``"right"`` (outflow), ``"bottom"``, ``"top"``
        (walls) and ``"particle0"`` (the cylinder).
    """
    import meshing

    sides = int(in_range("sides", sides, 16, 2048, integer=True))
    if sides % 2:
        raise ValueError(f"sides = {sides!r}: must be an even integer in [16, 2048] "
                         "(a vertex on each pressure probe)")
    h_max = float(in_range("h_max", h_max, 0.002, 0.2))
    h_out = h_max if h_outlet is None else float(in_range("h_outlet", h_outlet, h_max, 0.2))
    x0 = float(in_range("wake_end", wake_end, 0.3, LENGTH))
    a = 2.0 * np.pi * np.arange(sides) / sides
    cylinder = np.vstack([CENTER[0] + RADIUS * np.cos(a), CENTER[1] + RADIUS * np.sin(a)])

    def size(x):
        s = np.clip((x[0] - x0) / max(LENGTH - x0, 1e-12), 0.0, 1.0)
        return h_max + (h_out - h_max) * s

    return meshing.field_mesh((0.0, 0.0, LENGTH, HEIGHT), [cylinder], sigma=sigma, size=size)


def inflow_speed(case: str, ramp: float = 1.0) -> Callable[[float], float]:
    """The centreline inflow speed ``U(t)`` of a case.

    Parameters
    ----------
    case : {"2D-2", "2D-3"}
    ramp : float
        2D-2 only: ``U`` rises as ``1.5 (1 - cos(pi t / ramp)) / 2`` to 1.5 at
        ``t = ramp``, ``ramp`` in [0, 100] (0: 1.5 from the start).

    Returns
    -------
    callable
        ``U(t)``.
    """
    _check_case(case)
    if case == "2D-3":
        return lambda t: U_MAX * math.sin(math.pi * t / 8.0)
    ramp = float(in_range("ramp", ramp, 0.0, 100.0))
    return lambda t: U_MAX if t >= ramp else U_MAX * 0.5 * (1.0 - math.cos(math.pi * t / ramp))


def _check_case(case) -> str:
    if case not in CASES:
        raise ValueError(f"case = {case!r}: must be one of {list(CASES)}")
    return case


def _boundary_data(case: str, ramp: float) -> dict:
    speed = inflow_speed(case, ramp)

    def inflow(x, y, t):
        return 4.0 * speed(t) * y * (HEIGHT - y) / HEIGHT**2, 0.0 * y

    data: dict[str, object] = {name: (0.0, 0.0) for name in (*WALLS, CYLINDER)}
    data[INLET] = inflow  # set last: it owns the corner DOFs (0 there anyway)
    return data


@dataclass
class DFGSeries:
    """The time series of one DFG run and what it cost.

    Attributes
    ----------
    case : str
        ``"2D-2"`` or ``"2D-3"``.
    t, cd, cl, dp : ndarray
        Times of the accepted steps, drag and lift coefficients, pressure difference
        ``p(0.15, 0.2) - p(0.25, 0.2)``.
    dofs, triangles : int
        Unknowns (velocity and pressure) and triangles of the mesh.
    dt : float
        The (initial) step.
    rejected, refreshes, iterations : int
        Rejected step attempts, Newton Jacobians factorised after a stalled chord
        iteration, corrector iterations, summed over the run.
    cpu_time, wall_time : float
        Process CPU time and wall time of the time loop, seconds.
    flow : Flow
        The last state (a warm start for another run, :func:`run_dfg`'s ``initial``).
    info : dict
        ``t0``, ``t_end``, ``tol``, ``ramp`` and the smallest and largest step taken.
    """

    case: str
    t: np.ndarray
    cd: np.ndarray
    cl: np.ndarray
    dp: np.ndarray
    dofs: int
    triangles: int
    dt: float
    rejected: int = 0
    refreshes: int = 0
    iterations: int = 0
    cpu_time: float = 0.0
    wall_time: float = 0.0
    flow: Flow | None = None
    info: dict = field(default_factory=dict)

    @property
    def steps(self) -> int:
        """Accepted time steps."""
        return int(self.t.size)


def _check_run(case, dt, t_end, tol, t0: float) -> tuple[float, float, float | None]:
    _check_case(case)
    dt = float(in_range("dt", dt, 1e-6, 0.1))
    hi = T_END_2D3 if case == "2D-3" else 1000.0
    if t_end is None:
        t_end = T_END_2D3 if case == "2D-3" else t0 + 30.0
    t_end = float(in_range("t_end", t_end, t0 + dt, hi))
    if tol is not None:
        tol = float(in_range("tol", tol, 1e-8, 0.1))
    return dt, t_end, tol


def _start(initial) -> dict:
    """``evolve`` options of a run that starts from ``initial`` (a Flow, any mesh)."""
    if initial is None:
        return {}
    if not isinstance(initial, Flow) or initial.t is None:
        raise ValueError(f"initial = {type(initial).__name__}: must be the Flow of an unsteady "
                         "run (e.g. DFGSeries.flow), with its time")

    def u0(x, y):  # P2 nodes of the new mesh; a finer polygon lies just outside a coarser one
        return tuple(initial.velocity(np.vstack([x, y]), tol=START_TOL))

    return {"u0": u0, "t0": float(initial.t)}


def run_dfg(case: str, mesh, dt: float, t_end: float | None = None, *, tol: float | None = None,
            solver="auto", ramp: float = 1.0, initial: Flow | None = None) -> DFGSeries:
    """Run a DFG case with the library's BDF2 solver; the coefficient time series.

    Parameters
    ----------
    case : {"2D-2", "2D-3"}
    mesh : skfem.MeshTri
        A :func:`channel_mesh` (boundaries ``left``, ``right``, ``bottom``, ``top``,
        ``particle0``).
    dt : float
        Step (the initial one when adaptive), in [1e-6, 0.1].
    t_end : float, optional
        End time, in [t0 + dt, 8] for 2D-3 (default 8) and [t0 + dt, 1000] for 2D-2
        (default t0 + 30); ``t0`` is 0 or the time of ``initial``.
    tol : float, optional
        Adaptive steps with this local error tolerance (relative to 1.5), in
        [1e-8, 0.1]; ``None`` (default): fixed steps (halved only where the
        corrector fails).
    solver
        Linear solver, as in :func:`~skfem_granular.fluid.solve_steady`.
    ramp : float
        2D-2: inflow ramp time (see :func:`inflow_speed`).
    initial : Flow, optional
        Start from this flow at its time (the velocity interpolated to ``mesh``; e.g.
        the ``flow`` of a coarser run of the same case) instead of from rest at 0.
        2D-2's periodic state does not depend on where it started; a warm start
        saves the fine mesh the spin-up.

    Returns
    -------
    DFGSeries
    """
    options = _start(initial)
    dt, t_end, tol = _check_run(case, dt, t_end, tol, options.get("t0", 0.0))
    steps = evolve(mesh, Fluid(DENSITY, VISCOSITY), _boundary_data(case, ramp), dt=dt,
                   t_end=t_end, adaptive=tol is not None, tol=1e-3 if tol is None else tol,
                   convection=True, viscous="laplace", velocity_scale=U_MAX, solver=solver,
                   max_iterations=MAX_ITERATIONS, **options)
    cpu0, wall0 = time.process_time(), time.perf_counter()
    rows, totals, flow = _record(steps)
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    n_p = mesh.p.shape[1]
    return DFGSeries(case, rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3],
                     dofs=int(2 * (n_p + mesh.facets.shape[1]) + n_p),
                     triangles=int(mesh.t.shape[1]), dt=dt, rejected=int(totals[0]),
                     refreshes=int(totals[1]), iterations=int(totals[2]), cpu_time=cpu,
                     wall_time=wall, flow=flow,
                     info={"t0": options.get("t0", 0.0), "t_end": t_end, "tol": tol,
                           "ramp": ramp, "dt_min": float(rows[:, 4].min(initial=dt)),
                           "dt_max": float(rows[:, 4].max(initial=0.0))})


def _record(steps) -> tuple[np.ndarray, np.ndarray, Flow | None]:
    """Run the generator; rows ``(t, c_D, c_L, dp, dt)``, the summed (rejected,
    refreshes, iterations) and the last flow."""
    rows, probe, totals, flow = [], None, np.zeros(3, dtype=int), None
    scale = 2.0 / (DENSITY * U_MEAN**2 * DIAMETER)
    for t, flow in steps:
        if probe is None:
            cells, X = PointLocator(flow.mesh).locate(PROBES, name="pressure probes")
            probe = evaluation_matrix(flow.space.pb, cells, X)
        fx, fy = flow.force(CYLINDER)
        p = probe @ flow.p
        st = flow.step
        rows.append((t, scale * fx, scale * fy, p[0] - p[1], st.dt))
        totals += (st.rejected, st.refreshes, st.iterations)
    return np.array(rows, dtype=float).reshape(-1, 5), totals, flow


def peak(t, y) -> tuple[float, float]:
    """The largest value of a sampled curve and its time, refined by a parabola.

    The parabola goes through the largest sample and its two neighbours (any
    spacing); at either end of the series the sample itself is returned.

    Parameters
    ----------
    t, y : (n,) array_like
        Increasing times and values, ``n >= 1``.

    Returns
    -------
    value, time : float
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if t.ndim != 1 or t.shape != y.shape or t.size == 0:
        raise ValueError(f"t, y: must be 1-D arrays of equal length >= 1, got shapes "
                         f"{t.shape} and {y.shape}")
    k = int(np.argmax(y))
    if k == 0 or k == t.size - 1:
        return float(y[k]), float(t[k])
    c = np.polyfit(t[k - 1:k + 2] - t[k], y[k - 1:k + 2], 2)
    if c[0] >= 0.0:  # flat: no interior maximum of the parabola
        return float(y[k]), float(t[k])
    s = -c[1] / (2.0 * c[0])
    return float(np.polyval(c, s)), float(t[k] + s)


def lift_period(t, cl, t_from: float) -> tuple[float, int]:
    """Mean period of the lift after ``t_from`` from its upward mean crossings.

    Parameters
    ----------
    t, cl : (n,) array_like
        Times and lift coefficients.
    t_from : float
        Start of the window (the periodic state).

    Returns
    -------
    period : float
        Mean time between upward crossings of the window's mean lift (linear
        interpolation between samples).
    periods : int
        Whole periods in the window.

    Raises
    ------
    ValueError
        When the window holds fewer than two crossings.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(cl, dtype=float)
    w = t >= t_from
    tw, yw = t[w], y[w] - y[w].mean()
    up = np.flatnonzero((yw[:-1] < 0.0) & (yw[1:] >= 0.0))
    if up.size < 2:
        raise ValueError(f"t_from = {t_from!r}: the lift after it crosses its mean upwards "
                         f"{up.size} times; at least 2 are needed (run longer)")
    tc = tw[up] - yw[up] * (tw[up + 1] - tw[up]) / (yw[up + 1] - yw[up])
    return float((tc[-1] - tc[0]) / (tc.size - 1)), int(tc.size - 1)


def dfg2d3_summary(series: DFGSeries) -> dict:
    """2D-3: the maxima, their times and ``dp(8)``, with errors against John (2004).

    Returns
    -------
    dict
        ``cd_max``, ``t_cd_max``, ``cl_max``, ``t_cl_max``, ``dp_end`` and their
        errors ``err_<name>`` (relative for the values, absolute for the times).
    """
    if series.case != "2D-3":
        raise ValueError(f"series.case = {series.case!r}: must be '2D-3'")
    cd, tcd = peak(series.t, series.cd)
    cl, tcl = peak(series.t, series.cl)
    out = {"cd_max": cd, "t_cd_max": tcd, "cl_max": cl, "t_cl_max": tcl,
           "dp_end": float(series.dp[-1]), "t_end": float(series.t[-1])}
    ref = DFG2D3_REFERENCE
    for k in ("cd_max", "cl_max", "dp_end"):
        out[f"err_{k}"] = out[k] / ref[k] - 1.0
    for k in ("t_cd_max", "t_cl_max"):
        out[f"err_{k}"] = out[k] - ref[k]
    return out


def dfg2d2_summary(series: DFGSeries, periods: int = 5) -> dict:
    """2D-2: largest drag and lift over the last ``periods`` lift periods and ``St``.

    Parameters
    ----------
    series : DFGSeries
        A 2D-2 run long enough to reach the periodic state.
    periods : int
        Periods at the end of the run to evaluate, in [2, 1000].

    Returns
    -------
    dict
        ``cd_max``, ``cl_max``, ``strouhal`` (``D / (U_mean T)``), ``period``,
        ``cd_mean``, ``cl_min``, ``dp_max``, the window start ``t_from``, ``drift``
        (change of ``c_L,max`` between the window's first and last period, relative),
        and ``within`` (each quantity inside its Schaefer-Turek interval).
    """
    if series.case != "2D-2":
        raise ValueError(f"series.case = {series.case!r}: must be '2D-2'")
    periods = int(in_range("periods", periods, 2, 1000, integer=True))
    t = series.t
    period, _ = lift_period(t, series.cl, t[-1] - (periods + 1) * _rough_period(series))
    t_from = float(t[-1] - periods * period)
    w = t >= t_from
    first = w & (t < t_from + period)
    last = t >= t[-1] - period
    cl_first, cl_last = peak(t[first], series.cl[first])[0], peak(t[last], series.cl[last])[0]
    values = {"cd_max": peak(t[w], series.cd[w])[0], "cl_max": peak(t[w], series.cl[w])[0],
              "strouhal": DIAMETER / (U_MEAN * period), "period": period,
              "cd_mean": float(series.cd[w].mean()), "cl_min": float(series.cl[w].min()),
              "dp_max": float(series.dp[w].max()), "t_from": t_from,
              "drift": cl_last / cl_first - 1.0}
    within = {k: bool(lo <= values[k] <= hi) for k, (lo, hi) in DFG2D2_INTERVALS.items()}
    return {**values, "within": within}


def _rough_period(series: DFGSeries) -> float:
    """A first period estimate from the last third of the run."""
    t = series.t
    return lift_period(t, series.cl, t[0] + 2.0 * (t[-1] - t[0]) / 3.0)[0]

