"""Column preparation: grains poured into a box of the column's width, DEM only, until at rest.

:func:`deposition` is the loop (a generator the caller may own);
:func:`prepare_column` draws the grains, runs the loop with the protocol of the
chosen state (:mod:`.protocol`) and measures the result (:class:`~.packing.Packing`).
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from ..dem import ContactLaw, DEMSystem, Particle, Polygon
from .fraction import solid_fraction
from .grains import SHAPES, diameter_range, grain_outlines
from .packing import Packing
from .protocol import FREEZE, PROTOCOLS, Protocol

__all__ = ["GUESS_FRACTION", "REST_SPEED", "column_width", "deposition", "prepare_column",
           "surface_height"]

#: solid fraction assumed when sizing the box for a wanted aspect ratio
GUESS_FRACTION = 0.8

#: a grain is at rest below this speed, in units of ``sqrt(g d_mean)``
REST_SPEED = 3e-3

#: the loose grid the grains start from: cells of this many largest bounding diameters
CELL = 1.05


def column_width(n: int, aspect: float, d_mean: float, size_ratio: float) -> float:
    """``L0`` such that ``n`` grains at :data:`GUESS_FRACTION` fill ``H0 = aspect L0``."""
    d_min, d_max = diameter_range(d_mean, size_ratio)
    mean_area = np.pi / 4.0 * (d_min**2 + d_min * d_max + d_max**2) / 3.0
    return math.sqrt(n * mean_area / (GUESS_FRACTION * aspect))


def _check(n, aspect, state, shape, size_ratio, width, d_max):
    if not (isinstance(n, int) and not isinstance(n, bool) and n >= 1):
        raise ValueError(f"packing.n = {n!r}: must be an integer >= 1")
    if not (isinstance(aspect, (int, float)) and 0.05 <= aspect <= 20.0):
        raise ValueError(f"packing.aspect = {aspect!r}: must be a number in [0.05, 20]")
    if not isinstance(state, Protocol) and state not in PROTOCOLS:
        raise ValueError(f"packing.state = {state!r}: must be one of {', '.join(PROTOCOLS)} "
                         "(or a Protocol)")
    if shape not in SHAPES:
        raise ValueError(f"packing.shape = {shape!r}: must be one of {', '.join(SHAPES)}")
    if not (isinstance(size_ratio, (int, float)) and 1.0 <= size_ratio <= 4.0):
        raise ValueError(f"packing.size_ratio = {size_ratio!r}: must be a number in [1, 4]")
    if width < 2.0 * CELL * d_max:
        raise ValueError(f"packing: {n} grains at aspect {aspect:g} make a column "
                         f"{width:.3g} m wide, less than two grains (d_max = {d_max:.3g} m): "
                         "the packing cannot fit; give more grains or a smaller aspect")


def _grid(outlines, width, rng):
    """Start positions on a loose grid over ``[0, width]``, rows from the floor up."""
    R = np.array([np.hypot(*P).max() for P in outlines])
    s = 2.0 * CELL * R.max()
    per_row = int(width // s)
    x = (np.arange(len(outlines)) % per_row + 0.5) * s + (width - per_row * s) / 2.0
    y = (np.arange(len(outlines)) // per_row + 0.5) * s
    room = 0.5 * s - R * CELL  # jitter that keeps the cell free
    x = x + rng.uniform(-1.0, 1.0, len(outlines)) * np.maximum(room, 0.0)
    return np.vstack([x, y]), float(y.max() + s)


def deposition(dem: DEMSystem, *, t_max: float, rest_speed: float, chunk: float = 5e-3,
               statistic: str = "max"):
    """Advance ``dem`` in chunks of ``chunk`` s until the grains are at rest.

    Yields ``(t, speed)`` after every chunk, ``speed`` the grains' largest speed
    (``statistic = "max"``) or their root-mean-square speed (``"rms"``: a few
    rattling grains do not hold the stage up); stops when ``speed < rest_speed``.

    Raises
    ------
    RuntimeError
        If the grains are not at rest by ``t_max``.
    """
    while dem.t < t_max:
        dem.advance(chunk)
        v = np.hypot(*dem.velocities)
        vmax = float(v.max() if statistic == "max" else np.sqrt(np.mean(v * v)))
        yield dem.t, vmax
        if vmax < rest_speed:
            return
    raise RuntimeError(f"deposition: grains still moving at t = {dem.t:.3g} s ({statistic} speed "
                       f"{vmax:.3g} m/s > {rest_speed:.3g} m/s); raise t_max")


def _max_overlap(dem: DEMSystem) -> float:
    """Largest overlap area between two grains of the last step over the smaller's area."""
    cf = dem.contacts
    if cf is None:  # no step taken yet
        return 0.0
    grains = cf.j < dem.n
    if not grains.any():
        return 0.0
    i, j = cf.i[grains], cf.j[grains]
    area = dem.particles.area
    return float((cf.area[grains] / np.minimum(area[i], area[j])).max())


def surface_height(outlines, width: float, strip: float) -> float:
    """Mean over strips of width ``strip`` across ``[0, width]`` of the highest grain point."""
    V = np.concatenate([np.asarray(P) for P in outlines], axis=1)
    k = np.clip((V[0] / strip).astype(int), 0, max(int(width // strip) - 1, 0))
    top = np.full(k.max() + 1, -np.inf)
    np.maximum.at(top, k, V[1])
    return float(top[np.isfinite(top)].mean())


def prepare_column(n: int, aspect: float, state: str | Protocol = "dense", *, shape: str = "ngon",
                   d_mean: float = 1e-3, size_ratio: float = 1.8, sides: int = 12,
                   density: float = 2650.0, E: float = 1e6, seed: int = 0,
                   margin: float | None = None, t_max: float = 3.0, gravity: float = 9.81,
                   progress=None) -> Packing:
    """A column of ``n`` grains at rest in a box of width ``L0``, dense or loose.

    Parameters
    ----------
    n : int
        Number of grains.
    aspect : float
        Wanted ``a = H0 / L0``: the box width is chosen for it at a solid fraction of
        :data:`GUESS_FRACTION`; the packing reports the aspect it reached.
    state : {"dense", "loose"} or Protocol
        The deposition protocol (:data:`~skfem_granular.packing.PROTOCOLS`), or one of
        one's own (the packing's ``state`` then reads ``"mu=<friction>"``).
    shape, sides, d_mean, size_ratio
        Grains (:func:`~skfem_granular.packing.grain_outlines`).
    density : float
        Grain density (kg/m^3).
    E : float
        Contact stiffness during deposition (soft: large DEM steps). The grains rest with
        overlaps ``~ rho g H0 / E`` of their area (a few tenths of a percent for 1000
        grains at 1e6 N/m; the packing records the largest, :attr:`Packing.max_overlap`,
        and a collapse runs with the same stiffness).
    seed : int
        Seeds sizes, shapes, orientations and start positions: the same seed gives the
        same packing bit for bit.
    margin : float, optional
        The solid fraction is measured this many ``d_max`` away from the walls, the
        floor and the free surface. Default 2, and 0.5 for columns of fewer than 100
        grains (too small to leave a window 2 ``d_max`` inside their edges).
    t_max : float
        Simulated time allowed for the grains to come to rest (s).
    progress : callable, optional
        Called as ``progress(t, speed)`` after every chunk of the deposition (the rms
        speed in the first stage, the largest in the second).

    Returns
    -------
    Packing
        Its outlines are shifted by the grains' overlap with the left wall and the floor
        (a few micrometres), so that they lie in ``x, y >= 0``.
    """
    d_min, d_max = diameter_range(d_mean, size_ratio)
    width = column_width(n, aspect, d_mean, size_ratio) if isinstance(aspect, (int, float)) \
        and not isinstance(aspect, bool) and aspect > 0 else 0.0
    _check(n, aspect, state, shape, size_ratio, width, d_max)
    if margin is None:
        margin = 2.0 if n >= 100 else 0.5
    m = margin * d_max
    if not (width > 2 * m and aspect * width > 2 * m):
        raise ValueError(f"packing.margin = {margin!r}: the column ({width:.3g} x "
                         f"{aspect * width:.3g} m) is too small to measure its solid fraction "
                         f"{margin:g} d_max from its edges; give more grains or a smaller margin")
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    local = grain_outlines(n, shape, d_mean, size_ratio, rng, sides=sides)
    X, top = _grid(local, width, rng)
    grains = [Particle(Polygon(P + X[:, [k]]), density, core_ratio=1.0)
              for k, P in enumerate(local)]
    proto = state if isinstance(state, Protocol) else PROTOCOLS[state]
    name = f"mu={proto.mu:g}" if isinstance(state, Protocol) else state
    law = ContactLaw(E=E, mu=proto.mu, gamma=proto.gamma)
    dem = DEMSystem.in_box(grains, (0.0, 0.0, width, top), d_max, law=law,
                           gravity=(0.0, -gravity))
    rest = REST_SPEED * math.sqrt(gravity * d_mean)
    for stage_mu, speed, stat in ((proto.mu, FREEZE * rest, "rms"),
                                  (proto.settle_mu, rest, "max")):
        dem.law = replace(law, mu=stage_mu)
        for t, vmax in deposition(dem, t_max=t_max, rest_speed=speed, statistic=stat):
            if progress is not None:
                progress(t, vmax)
    V = dem.shadow_outlines()
    overlap = _max_overlap(dem)
    lift = np.array([[max(0.0, -min(P[0].min() for P in V))],
                     [max(0.0, -min(P[1].min() for P in V))]])
    outlines = tuple(P + lift for P in V)
    H0 = surface_height(outlines, width, d_max)
    window = (m, m, width - m, H0 - m)
    if not (window[2] > window[0] and window[3] > window[1]):
        raise ValueError(f"packing: column {width:.3g} x {H0:.3g} m too small to measure "
                         f"its solid fraction {margin:g} d_max from its edges; give more "
                         "grains or a smaller margin")
    return Packing(outlines=outlines, density=float(density), width=float(width),
                   height=H0, solid_fraction=solid_fraction(outlines, window), state=name,
                   shape=shape, seed=int(seed), d_mean=float(d_mean),
                   size_ratio=float(size_ratio), E=float(E), window=window,
                   settle_time=float(dem.t), max_overlap=overlap,
                   wall_time=time.perf_counter() - t0)
