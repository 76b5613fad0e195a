"""The ``[grid]`` section: an ``nx`` x ``ny`` block of regular polygons (the paper's Section 7)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..dem import Polygon
from ._checks import MAX_LENGTH, MAX_SIDES, integer, num, vec
from ._keys import Docs, KeyDoc
from .sections import ParticleSpec

__all__ = ["GRID_DOCS", "GRID_SPACING", "MAX_GRID", "GridSpec"]

#: Centre distance of a grid over the polygons' radius when ``spacing`` is not given.
GRID_SPACING = 2.2
#: Most polygons along one side of a grid.
MAX_GRID = 100


@dataclass(frozen=True, kw_only=True)
class GridSpec:
    """A block of equal regular polygons, row by row from ``origin``; validated on construction.

    Attributes
    ----------
    nx, ny : int
        Polygons along x and along y.
    sides : int
        Sides of each polygon.
    radius : float
        Circumradius (m).
    spacing : float or None
        Centre distance (m), more than twice the radius; None: :data:`GRID_SPACING` radii.
    origin : (x, y)
        Centre of the first polygon (m).
    density : float
        Grain density (kg/m^3).
    core_ratio : float
        The fluid's outline over the contact outline.
    jitter : float
        Each polygon turned by a uniform random angle in ``[-jitter, jitter]`` (rad).
    seed : int
        Seed of the random angles.
    """

    nx: int
    ny: int
    sides: int = 6
    radius: float
    spacing: float | None = None
    origin: tuple
    density: float = 2650.0
    core_ratio: float = 0.8
    jitter: float = 0.0
    seed: int = 0

    def __post_init__(self):
        for key in ("nx", "ny"):
            integer("grid", key, getattr(self, key), 1, MAX_GRID)
        integer("grid", "sides", self.sides, 3, MAX_SIDES)
        integer("grid", "seed", self.seed, 0)
        r = num("grid", "radius", self.radius, lo=0, hi=MAX_LENGTH)
        s = GRID_SPACING * r if self.spacing is None else self.spacing
        checked = {
            "radius": r,
            "spacing": num("grid", "spacing", s, lo=2 * r, hi=MAX_LENGTH),
            "origin": vec("grid", "origin", self.origin, bound=MAX_LENGTH),
            "density": num("grid", "density", self.density, lo=0),
            "core_ratio": num("grid", "core_ratio", self.core_ratio, lo=0, hi=1),
            "jitter": num("grid", "jitter", self.jitter, lo=0, lo_open=False, hi=np.pi),
        }
        for key, value in checked.items():
            object.__setattr__(self, key, value)

    def particles(self) -> list[ParticleSpec]:
        """The polygons, row by row (x fastest)."""
        rng = np.random.default_rng(self.seed)
        ox, oy = self.origin
        s = GRID_SPACING * self.radius if self.spacing is None else self.spacing
        out = []
        for j in range(self.ny):
            for i in range(self.nx):
                c = (ox + i * s, oy + j * s)
                ang = rng.uniform(-self.jitter, self.jitter) if self.jitter else 0.0
                out.append(ParticleSpec(Polygon.regular(self.sides, self.radius, center=c,
                                                        angle=ang),
                                        self.density, core_ratio=self.core_ratio))
        return out


#: The TOML keys of ``[grid]``: one per field of :class:`GridSpec`.
GRID_DOCS: Docs = {
    "nx": KeyDoc("integer", "polygons along x", f"in [1, {MAX_GRID}]"),
    "ny": KeyDoc("integer", "polygons along y (rows)", f"in [1, {MAX_GRID}]"),
    "sides": KeyDoc("integer", "sides of each regular polygon", f"in [3, {MAX_SIDES}]"),
    "radius": KeyDoc("float", "circumradius of each polygon", f"> 0 and <= {MAX_LENGTH:g}",
                     "m"),
    "spacing": KeyDoc("float", f"centre distance; not given: {GRID_SPACING:g} radius",
                      f"> 2 radius and <= {MAX_LENGTH:g}", "m"),
    "origin": KeyDoc("[float, float]", "centre of the first (lower left) polygon",
                     f"2 finite numbers within +-{MAX_LENGTH:g}", "m"),
    "density": KeyDoc("float", "grain density", "> 0", "kg/m^3"),
    "core_ratio": KeyDoc("float", "the fluid's outline: the polygon scaled by this",
                         "> 0 and <= 1"),
    "jitter": KeyDoc("float", "each polygon turned by a random angle in [-jitter, jitter]",
                     ">= 0 and <= pi", "rad"),
    "seed": KeyDoc("integer", "seed of the random angles", ">= 0"),
}
