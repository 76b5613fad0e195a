"""The sections of a scene: effects, mesh, time span and particles, validated on construction."""

from __future__ import annotations

import inspect
from dataclasses import dataclass, fields

from ..dem import Particle, Polygon, PrescribedMotion
from ._checks import MAX_ANGLE, MAX_LENGTH, MAX_SIDES, num
from ._keys import REQUIRED, Docs, KeyDoc


@dataclass(frozen=True)
class Effects:
    """The physics a scene calls for.

    Attributes
    ----------
    fluid : bool
        Off: dry DEM, no mesh at all.
    gravity : bool
        Buoyancy-reduced gravity on the particles.
    convection : bool
        Navier-Stokes (on) or unsteady Stokes (off: no Newton loop, one
        reused factorisation).
    contacts : bool or "auto"
        DEM contacts; ``"auto"`` turns them on only when a pair of shadows
        (or a shadow and a wall) could meet within the run.
    rotation : bool
        Particles may rotate.
    remeshing : bool
        Rebuild the mesh when particles have moved (otherwise the run stops
        with an error if they move too far for the fixed mesh).
    """

    fluid: bool = True
    gravity: bool = True
    convection: bool = True
    contacts: bool | str = "auto"
    rotation: bool = True
    remeshing: bool = True

    def __post_init__(self):
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "contacts" and v == "auto":
                continue
            if not isinstance(v, bool):
                allowed = "true, false or 'auto'" if f.name == "contacts" else "true or false"
                raise ValueError(f"effects.{f.name} = {v!r}: must be {allowed}")


_BOOL = "true or false"
#: The TOML keys of ``[effects]``: one per field of :class:`Effects`.
EFFECTS_DOCS: Docs = {
    "fluid": KeyDoc("bool", "the fluid; off: dry DEM, no mesh at all", _BOOL),
    "gravity": KeyDoc("bool", "buoyancy-reduced gravity on the particles", _BOOL),
    "convection": KeyDoc("bool", "Navier-Stokes; off: unsteady Stokes (one reused "
                         "factorisation)", _BOOL),
    "contacts": KeyDoc('bool or "auto"', "DEM contacts; \"auto\": on only when two shadows "
                       "(or a shadow and a wall) can meet within the run",
                       'true, false or "auto"'),
    "rotation": KeyDoc("bool", "particles may rotate", _BOOL),
    "remeshing": KeyDoc("bool", "rebuild the mesh when particles have moved (off: the run "
                        "stops when they move too far)", _BOOL),
}


MESH_KINDS = ("auto", "field", "graded", "uniform", "group")
"""The values of ``mesh.kind``."""


@dataclass(frozen=True)
class MeshSpec:
    """Discretisation of the fluid domain (see :mod:`meshing` and docs/meshing.md).

    ``kind``: ``"auto"`` (default: ``"graded"`` concentric circles for one
    particle, the ``"field"`` size-field mesh for more), ``"graded"``,
    ``"field"``, ``"uniform"`` or ``"group"`` (the paper's Fig. 13).
    ``gap_spacing`` (``"field"`` meshes only): outline node spacing along narrow gaps
    as a fraction of the gap's width, ``>= 0.1`` (default 1/3; a large value such as
    100 leaves the gaps unlined).

    ``wake`` (default true): a ``"graded"`` mesh with the default ``sigma`` is
    remeshed with finer circles while a particle's Reynolds number is above 40
    (:class:`~skfem_granular.coupled.wake.WakeGrading`; quiet flows keep the
    paper's mesh bit for bit); false keeps the paper's circles at every speed.
    """

    kind: str = "auto"
    delta_l: float | None = None
    sigma: float | None = None
    h: float | None = None
    gap_spacing: float | None = None
    wake: bool = True

    def __post_init__(self):
        if self.kind not in MESH_KINDS:
            raise ValueError(f"mesh.kind = {self.kind!r}: must be 'auto', 'field', "
                             "'graded', 'uniform' or 'group'")
        object.__setattr__(
            self, "delta_l", num("mesh", "delta_l", self.delta_l, lo=0, allow_none=True)
        )
        object.__setattr__(self, "h", num("mesh", "h", self.h, lo=0, allow_none=True))
        if self.sigma is not None:
            object.__setattr__(self, "sigma", num("mesh", "sigma", self.sigma, lo=1.0, hi=1.6))
        if self.gap_spacing is not None:
            object.__setattr__(self, "gap_spacing", num("mesh", "gap_spacing", self.gap_spacing,
                                                        lo=0.1, lo_open=False))
            if self.kind not in ("auto", "field"):
                raise ValueError(f"mesh.gap_spacing: only for kind 'field' (or 'auto' with "
                                 f"several particles), not {self.kind!r}")
        if not isinstance(self.wake, bool):
            raise ValueError(f"mesh.wake = {self.wake!r}: must be true or false")


#: The TOML keys of ``[mesh]``: one per field of :class:`MeshSpec`.
MESH_DOCS: Docs = {
    "kind": KeyDoc("string", "\"auto\": \"graded\" for one particle, \"field\" for more; "
                   "\"group\": the paper's Fig. 13",
                   ", ".join(f'"{k}"' for k in MESH_KINDS[:-1]) + f' or "{MESH_KINDS[-1]}"'),
    "delta_l": KeyDoc("float", "mesh edge length on the particle outlines; not given: the "
                      "polygon's edge length", "> 0", "m"),
    "sigma": KeyDoc("float", "growth of the mesh size away from the particles; not given: "
                    "the mesh kind's own", "> 1 and <= 1.6"),
    "h": KeyDoc("float", "edge length of \"uniform\" meshes and of the fine region of "
                "\"group\" meshes; not given: the outlines' mean edge", "> 0", "m"),
    "gap_spacing": KeyDoc("float", "\"field\" meshes: outline node spacing along narrow gaps, "
                          "over the gap's width; not given: 1/3", ">= 0.1"),
    "wake": KeyDoc("bool", "\"graded\" meshes with the default sigma: finer circles while a "
                   "particle's Reynolds number is above 40", _BOOL),
}


@dataclass(frozen=True)
class TimeSpec:
    """Time span and steps (seconds).

    Attributes
    ----------
    t_end : float
        End time, > 0.
    dt : float
        The step (fixed steps), or the first step and the largest (adaptive).
    dem_dt : float or None
        DEM subcycle step (None: from the contact stiffness).
    adaptive : bool
        Choose the steps of a coupled run from the BDF2 local error estimate
        (accept/reject), at most ``dt``.
    tol : float
        Local error tolerance relative to the velocity scale, in (0, 1].
    dt_min : float
        Smallest step of an adaptive run; a step that would need less stops
        the run with a clear error.
    contact_warning : bool
        Warn when fixed steps with contacts are longer than a contact needs
        (bounces come out more damped than the contact law makes them); false
        for a scene whose step is coarse on purpose.
    """

    t_end: float = 1e-3
    dt: float = 1e-5
    dem_dt: float | None = None
    adaptive: bool = False
    tol: float = 1e-3
    dt_min: float = 1e-12
    contact_warning: bool = True

    def __post_init__(self):
        object.__setattr__(self, "t_end", num("time", "t_end", self.t_end, lo=0))
        object.__setattr__(self, "dt", num("time", "dt", self.dt, lo=0))
        object.__setattr__(
            self, "dem_dt", num("time", "dem_dt", self.dem_dt, lo=0, allow_none=True)
        )
        if self.dt > self.t_end:
            raise ValueError(f"time.dt = {self.dt:g}: must be <= time.t_end = {self.t_end:g}")
        if not isinstance(self.adaptive, bool):
            raise ValueError(f"time.adaptive = {self.adaptive!r}: must be true or false")
        object.__setattr__(self, "tol", num("time", "tol", self.tol, lo=0, hi=1))
        object.__setattr__(self, "dt_min", num("time", "dt_min", self.dt_min, lo=0))
        if self.dt_min > self.dt:
            raise ValueError(f"time.dt_min = {self.dt_min:g}: must be <= time.dt = {self.dt:g}")
        if not isinstance(self.contact_warning, bool):
            raise ValueError(f"time.contact_warning = {self.contact_warning!r}: must be true "
                             "or false")


#: The TOML keys of ``[time]``: one per field of :class:`TimeSpec`.
TIME_DOCS: Docs = {
    "t_end": KeyDoc("float", "end time", "> 0", "s"),
    "dt": KeyDoc("float", "the step (fixed steps), or the first and largest step (adaptive)",
                 "> 0 and <= time.t_end", "s"),
    "dem_dt": KeyDoc("float", "DEM subcycle step; not given: from the contact stiffness",
                     "> 0 and <= the stable DEM step", "s"),
    "adaptive": KeyDoc("bool", "steps chosen from the BDF2 local error estimate, at most dt",
                       _BOOL),
    "tol": KeyDoc("float", "adaptive steps: local error tolerance relative to the velocity "
                  "scale", "> 0 and <= 1"),
    "dt_min": KeyDoc("float", "adaptive steps: the smallest; a step that would need less "
                     "stops the run", "> 0 and <= time.dt", "s"),
    "contact_warning": KeyDoc("bool", "warn when fixed steps with contacts exceed 1.25 DEM "
                              "stable steps (bounces more damped than the contact law); "
                              "false: the step is coarse on purpose", _BOOL),
}


@dataclass(frozen=True)
class ParticleSpec:
    """One particle: a convex polygon (shadow), its density, initial state and core.

    Attributes
    ----------
    polygon : Polygon
    density : float
    velocity : (2,) tuple
        Initial velocity (m/s).
    angular_velocity : float
        Initial angular velocity (rad/s).
    core_ratio : float
        The fluid's outline (core) is the polygon scaled by this about its centroid.
    motion : PrescribedMotion or None
        An imposed rigid motion (TOML ``motion = {velocity = [U, V], omega = w}`` or
        ``motion = {trajectory = [[t...], [x...], [y...], [angle...]]}``; in Python also
        a function ``t -> (x, y, angle)``): the particle moves along it whatever the
        forces, the fluid sees its velocity as boundary data and the history reports
        the fluid force on it (:mod:`skfem_granular.dem.motion`). ``None``: free.
    """

    polygon: Polygon
    density: float
    velocity: tuple = (0.0, 0.0)
    angular_velocity: float = 0.0
    core_ratio: float = 1.0
    motion: PrescribedMotion | None = None

    def to_dem(self) -> Particle:
        """The DEM particle."""
        return Particle(
            self.polygon,
            self.density,
            velocity=self.velocity,
            angular_velocity=self.angular_velocity,
            core_ratio=self.core_ratio,
            motion=self.motion,
        )


#: The angle of a regular polygon's first vertex when not given (``Polygon.regular``'s).
DEFAULT_ANGLE = inspect.signature(Polygon.regular).parameters["angle"].default
_SHAPE = "give vertices, or sides, radius and center"
#: The TOML keys of a ``[[particles]]`` entry: one per field of :class:`ParticleSpec`
#: (the polygon as its ``vertices`` or as a regular polygon's ``sides``, ``radius``,
#: ``center`` and ``angle``; ``motion`` is an inline table, ``MOTION_DOCS``).
PARTICLE_DOCS: Docs = {
    "polygon": (
        KeyDoc("[[float, ...], [float, ...]]", "the polygon's vertices [[x0, x1, ...], "
               "[y0, y1, ...]], convex and counter-clockwise", f"(2, N) finite; {_SHAPE}",
               "m", key="vertices", default=REQUIRED),
        KeyDoc("integer", "sides of a regular polygon", f"in [3, {MAX_SIDES}]; {_SHAPE}",
               key="sides", default=REQUIRED),
        KeyDoc("float", "circumradius of a regular polygon", f"> 0 and <= {MAX_LENGTH:g}", "m",
               key="radius", default=REQUIRED),
        KeyDoc("[float, float]", "centre of a regular polygon",
               f"2 finite numbers within +-{MAX_LENGTH:g}", "m", key="center",
               default=REQUIRED),
        KeyDoc("float", "angle of a regular polygon's first vertex from the x axis",
               f">= -{MAX_ANGLE:g} and <= {MAX_ANGLE:g}", "rad", key="angle",
               default=DEFAULT_ANGLE),
    ),
    "density": KeyDoc("float", "particle density", "> 0", "kg/m^3"),
    "velocity": KeyDoc("[float, float]", "initial velocity", "2 finite numbers", "m/s"),
    "angular_velocity": KeyDoc("float", "initial angular velocity (counter-clockwise)",
                               "a finite number", "rad/s"),
    "core_ratio": KeyDoc("float", "the fluid's outline (core): the polygon scaled by this "
                         "about its centroid", "> 0 and <= 1"),
    "motion": KeyDoc("inline table", "an imposed rigid motion (table below); not given: free",
                     "{ velocity, omega } or { trajectory }"),
}
