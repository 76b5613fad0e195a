"""Scene: a declarative description of a simulation, built in Python or read from TOML.

A scene names the geometry, the materials, the discretisation, the time span
and the *effects* it needs; :class:`~skfem_granular.simulation.Simulation`
builds only those. Every value is validated on construction and a bad one
raises a :class:`ValueError` with one line naming the field and the allowed
range (``"time.dt = -1: must be a finite number > 0"``).

TOML layout (see ``scenes/single_particle.toml``)::

    [domain]    box = [x0, y0, x1, y1], wall_thickness
    [fluid]     density, viscosity                  (omit for a dry scene)
    [[particles]] sides, radius, center, angle | vertices; density, velocity,
                angular_velocity, core_ratio
    [grid]      nx, ny, sides, radius, spacing, origin, density, core_ratio, jitter
    [contacts]  E, mu, gamma
    [mesh]      kind = "graded" | "uniform" | "group", delta_l, sigma, h
    [time]      t_end, dt, dem_dt, adaptive, tol, dt_min
    [effects]   fluid, gravity, convection, contacts, rotation, remeshing
    [coupling]  scheme = "monolithic" | "partitioned", remesh_fraction
    [output]    directory, vtu_every, checkpoint_every
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

import numpy as np

from .dem import ContactLaw, Particle, Polygon, stable_time_step
from .fluid.properties import Fluid


def _num(section, name, value, *, lo=None, hi=None, lo_open=True, allow_none=False):
    full = f"{section}.{name}"
    if value is None and allow_none:
        return None
    rng = []
    if lo is not None:
        rng.append(f"{'>' if lo_open else '>='} {lo:g}")
    if hi is not None:
        rng.append(f"<= {hi:g}")
    msg = f"{full} = {value!r}: must be a finite number {' and '.join(rng)}".rstrip()
    if isinstance(value, bool):  # float(True) == 1.0: a boolean is a typo, not a number
        raise ValueError(msg)
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(msg) from None
    ok = math.isfinite(x)
    if ok and lo is not None:
        ok = x > lo if lo_open else x >= lo
    if ok and hi is not None:
        ok = x <= hi
    if not ok:
        raise ValueError(msg)
    return x


def _vec(section, name, value, n=2):
    try:
        x = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{section}.{name} = {value!r}: must be {n} finite numbers") from None
    if x.size != n or not np.all(np.isfinite(x)):
        raise ValueError(f"{section}.{name} = {value!r}: must be {n} finite numbers")
    return tuple(float(v) for v in x)


def _check_keys(section: str, data: dict, allowed) -> None:
    unknown = sorted(set(data) - set(allowed))
    if unknown:
        raise ValueError(
            f"{section}: unknown key {unknown[0]!r}; allowed keys are {', '.join(sorted(allowed))}"
        )


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


@dataclass(frozen=True)
class MeshSpec:
    """Discretisation of the fluid domain (see :mod:`meshing`)."""

    kind: str = "graded"
    delta_l: float | None = None
    sigma: float | None = None
    h: float | None = None

    def __post_init__(self):
        if self.kind not in ("graded", "uniform", "group"):
            raise ValueError(f"mesh.kind = {self.kind!r}: must be 'graded', 'uniform' or 'group'")
        object.__setattr__(
            self, "delta_l", _num("mesh", "delta_l", self.delta_l, lo=0, allow_none=True)
        )
        object.__setattr__(self, "h", _num("mesh", "h", self.h, lo=0, allow_none=True))
        if self.sigma is not None:
            object.__setattr__(self, "sigma", _num("mesh", "sigma", self.sigma, lo=1.0, hi=1.6))


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
    """

    t_end: float = 1e-3
    dt: float = 1e-5
    dem_dt: float | None = None
    adaptive: bool = False
    tol: float = 1e-3
    dt_min: float = 1e-12

    def __post_init__(self):
        object.__setattr__(self, "t_end", _num("time", "t_end", self.t_end, lo=0))
        object.__setattr__(self, "dt", _num("time", "dt", self.dt, lo=0))
        object.__setattr__(
            self, "dem_dt", _num("time", "dem_dt", self.dem_dt, lo=0, allow_none=True)
        )
        if self.dt > self.t_end:
            raise ValueError(f"time.dt = {self.dt:g}: must be <= time.t_end = {self.t_end:g}")
        if not isinstance(self.adaptive, bool):
            raise ValueError(f"time.adaptive = {self.adaptive!r}: must be true or false")
        object.__setattr__(self, "tol", _num("time", "tol", self.tol, lo=0, hi=1))
        object.__setattr__(self, "dt_min", _num("time", "dt_min", self.dt_min, lo=0))
        if self.dt_min > self.dt:
            raise ValueError(f"time.dt_min = {self.dt_min:g}: must be <= time.dt = {self.dt:g}")


@dataclass(frozen=True)
class ParticleSpec:
    """One particle: a convex polygon (shadow), its density, initial state and core."""

    polygon: Polygon
    density: float
    velocity: tuple = (0.0, 0.0)
    angular_velocity: float = 0.0
    core_ratio: float = 1.0

    def to_dem(self) -> Particle:
        """The DEM particle."""
        return Particle(
            self.polygon,
            self.density,
            velocity=self.velocity,
            angular_velocity=self.angular_velocity,
            core_ratio=self.core_ratio,
        )


@dataclass(frozen=True)
class Scene:
    """Everything a simulation needs; validated on construction.

    Parameters
    ----------
    domain : (x0, y0, x1, y1)
        The fluid box (m); DEM walls of ``wall_thickness`` surround it.
    particles : list of ParticleSpec
    fluid : Fluid or None
        ``None`` (or ``effects.fluid = False``) makes a dry scene.
    gravity : (gx, gy)
    contact_law : ContactLaw
    mesh, time, effects
        :class:`MeshSpec`, :class:`TimeSpec`, :class:`Effects`.
    coupling : {"monolithic", "partitioned"}
    remesh_fraction : float
        Remesh when a particle has moved by this fraction of its outline
        edge length since the mesh was built.
    output_dir : str or None
    vtu_every : int
        Write the flow and outlines every this many steps (0: only the last).
    checkpoint_every : int
        Write ``checkpoint.pkl`` (the whole state: both BDF2 histories, DEM
        contact history, mesh, history rows) every this many steps; 0: never.
        ``Simulation.resume(directory)`` continues from it.
    name : str
    """

    domain: tuple
    particles: tuple
    fluid: Fluid | None = field(default_factory=Fluid)
    gravity: tuple = (0.0, -9.81)
    wall_thickness: float = 0.5e-3
    contact_law: ContactLaw = field(default_factory=ContactLaw)
    mesh: MeshSpec = field(default_factory=MeshSpec)
    time: TimeSpec = field(default_factory=TimeSpec)
    effects: Effects = field(default_factory=Effects)
    coupling: str = "monolithic"
    remesh_fraction: float = 0.25
    output_dir: str | None = None
    vtu_every: int = 10
    checkpoint_every: int = 0
    name: str = "scene"

    def __post_init__(self):
        for name, value, cls, what in (
            ("fluid", self.fluid, (Fluid, type(None)), "a Fluid or None (dry scene)"),
            ("contact_law", self.contact_law, ContactLaw, "a ContactLaw"),
            ("mesh", self.mesh, MeshSpec, "a MeshSpec"),
            ("time", self.time, TimeSpec, "a TimeSpec"),
            ("effects", self.effects, Effects, "an Effects"),
        ):
            if not isinstance(value, cls):
                raise ValueError(f"scene.{name} = {value!r}: must be {what}")
        d = _vec("domain", "box", self.domain, 4)
        if not (d[2] > d[0] and d[3] > d[1]):
            raise ValueError(
                f"domain.box = {list(d)}: must be (x0, y0, x1, y1) with x1 > x0, y1 > y0"
            )
        object.__setattr__(self, "domain", d)
        object.__setattr__(self, "gravity", _vec("scene", "gravity", self.gravity))
        _num("domain", "wall_thickness", self.wall_thickness, lo=0)
        if not isinstance(self.particles, (list, tuple)) or not self.particles:
            raise ValueError("particles: at least one particle is required")
        object.__setattr__(self, "particles", tuple(self.particles))
        for i, p in enumerate(self.particles):
            if not isinstance(p, ParticleSpec):
                raise ValueError(f"particles[{i}]: must be a ParticleSpec")
            if not isinstance(p.polygon, Polygon):
                raise ValueError(
                    f"particles[{i}].polygon: must be a Polygon, got {type(p.polygon).__name__}"
                )
            _num(f"particles[{i}]", "density", p.density, lo=0)
            _num(f"particles[{i}]", "core_ratio", p.core_ratio, lo=0, hi=1.0)
            _vec(f"particles[{i}]", "velocity", p.velocity)
            _num(f"particles[{i}]", "angular_velocity", p.angular_velocity)
            V = p.polygon.vertices
            if V[0].min() < d[0] or V[0].max() > d[2] or V[1].min() < d[1] or V[1].max() > d[3]:
                raise ValueError(f"particles[{i}]: polygon sticks out of domain.box {list(d)}")
        if self.coupling not in ("monolithic", "partitioned"):
            raise ValueError(
                f"coupling.scheme = {self.coupling!r}: must be 'monolithic' or 'partitioned'"
            )
        _num("coupling", "remesh_fraction", self.remesh_fraction, lo=0, hi=1.0)
        for key in ("vtu_every", "checkpoint_every"):
            v = getattr(self, key)
            if not (isinstance(v, int) and not isinstance(v, bool) and v >= 0):
                raise ValueError(f"output.{key} = {v!r}: must be an integer >= 0")
        if self.output_dir is not None and not isinstance(self.output_dir, (str, os.PathLike)):
            raise ValueError(
                f"output.directory = {self.output_dir!r}: must be a directory path (string)"
            )
        self._check_dem_dt()
        if self.fluid is None and self.effects.fluid:
            object.__setattr__(self, "effects", replace(self.effects, fluid=False))

    def _check_dem_dt(self) -> None:
        """``time.dem_dt`` must not exceed the DEM's stable step (named here, not as 'dt')."""
        if self.time.dem_dt is None:
            return
        mass = np.array([p.density * p.polygon.area for p in self.particles])
        law = self.contact_law
        bound = stable_time_step(mass, law.E, law.gamma)
        if self.time.dem_dt > bound * (1.0 + 1e-9):
            raise ValueError(
                f"time.dem_dt = {self.time.dem_dt:g}: must be <= {bound:.6g} s, the stable DEM "
                f"step 0.1*pi*sqrt(min m / contacts.E) / max(1, 2 contacts.gamma)"
            )

    @property
    def dry(self) -> bool:
        """True when the scene has no fluid."""
        return not self.effects.fluid

    def with_mesh(self, kind: str) -> Scene:
        """The same scene on another kind of mesh (``"graded"`` / ``"uniform"``)."""
        return replace(self, mesh=replace(self.mesh, kind=kind))

    @classmethod
    def from_toml(cls, path) -> Scene:
        """Read a scene from a TOML file (see the module docstring)."""
        path = Path(path)
        try:
            data = tomllib.loads(path.read_text())
        except FileNotFoundError:
            raise ValueError(f"scene file {str(path)!r}: not found") from None
        except IsADirectoryError:
            raise ValueError(f"scene file {str(path)!r}: is a directory, not a TOML file") from None
        except OSError as exc:
            raise ValueError(f"scene file {str(path)!r}: cannot read ({exc.strerror})") from None
        except UnicodeDecodeError:
            raise ValueError(f"scene file {str(path)!r}: not UTF-8 text (TOML required)") from None
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"scene file {str(path)!r}: not valid TOML ({exc})") from None
        scene = cls.from_dict(data, name=path.stem)
        if scene.output_dir is not None and not Path(scene.output_dir).is_absolute():
            scene = replace(scene, output_dir=str(Path(scene.output_dir)))
        return scene

    @classmethod
    def from_dict(cls, data: dict, name: str = "scene") -> Scene:
        """Build a scene from the nested dictionary of the TOML layout."""
        from .scene_parse import scene_kwargs

        return cls(name=name, **scene_kwargs(data))
