"""The :class:`Scene` dataclass: a whole simulation, built in Python or read from TOML."""

from __future__ import annotations

import os
import tomllib
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import ClassVar

import numpy as np

from ..dem import ContactLaw, Polygon, PrescribedMotion, stable_time_step
from ..fluid.properties import Fluid
from ._checks import num, vec
from ._keys import check_table
from .catalog import bundled
from .layout import SCENE_DOCS
from .parse import MAX_PARTICLES, scene_kwargs
from .sections import Effects, MeshSpec, ParticleSpec, TimeSpec

#: Largest scene file read (about 40 times the largest bundled scene's vertices per particle,
#: for :data:`~skfem_granular.scene.parse.MAX_PARTICLES` particles).
MAX_SCENE_BYTES = 20_000_000


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
    coupling : {"monolithic", "partitioned", "split"}
        ``"monolithic"``: fluid and rigid-body velocities in one Newton system (the
        reference); ``"split"``: pressure correction with the rigid velocities implicit in
        the projection (no coupled factorisation: for many grains); ``"partitioned"``: the
        paper's staggered scheme.
    remesh_fraction : float
        Fixed mesh: remesh when a particle has moved by this fraction of its
        outline edge length since the mesh was built.
    mesh_motion : {"auto", "ale", "fixed"}
        ``"auto"`` (default): ``"ale"`` with the monolithic and split couplings,
        ``"fixed"`` with the partitioned one (see :attr:`moving_mesh`).
        ``"fixed"``: the mesh stays until a remesh (the particle boundary lags
        behind the particle by up to ``remesh_fraction`` of an edge).
        ``"ale"``: the mesh moves with the particles every step (outline nodes
        rigidly, the rest by a smooth extension), the fluid in ALE form; remesh
        only when the moved mesh's quality drops or a particle has travelled
        ``remesh_travel`` radii from where its mesh was built.
    remesh_travel : float
        ALE: how far (in bounding radii) a particle may travel from the place
        its mesh was graded for before a remesh.
    mesh_repair : {"auto", "flips", "none"}
        ALE: what answers a remesh asked for by a few poor triangles. ``"flips"``: flip
        edges of the mesh in use where that keeps every triangle good (the vertices stay;
        a new mesh only when flips cannot); ``"none"``: a new mesh; ``"auto"`` (default):
        ``"flips"`` with the split coupling, ``"none"`` with the monolithic one.
    newton_tol : float
        The monolithic coupling's corrector stops when its update (or the error left,
        estimated from the contraction rate) is below this fraction of the velocity
        scale. The default 1e-6 leaves the grains' velocities within about 2e-4 of
        the largest grain speed of a tightly converged run in a dense immersed
        column, under 0.1 % of what halving the time step changes; a tighter
        tolerance costs Jacobian refreshes: docs/benchmarks.md, "The corrector's
        tolerance".
    output_dir : str or None
    vtu_every : int
        Write the flow and outlines every this many steps (0: only the last).
    checkpoint_every : int
        Write ``checkpoint.npz`` (plain data, the whole state: both BDF2
        histories, DEM contact history, mesh; the history rows stay in
        ``history.csv``, the one before kept as ``checkpoint.prev.npz``) every
        this many steps; 0: never (SIGINT/SIGTERM still write one).
        ``Simulation.resume(directory)`` continues from it.
    name : str
    overlap_tolerance : float
        Largest overlap area of two outlines at the start, over the smaller one's area
        (default 1e-3): a column at rest (``[column]``) overlaps by what its contact law
        needs to carry the column's weight, and sets it from its packing.
    """

    #: fields added after checkpoints were first written: read at their defaults from one
    #: that lacks them
    LATER_FIELDS: ClassVar[tuple[str, ...]] = ("mesh_repair",)

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
    mesh_motion: str = "auto"
    remesh_travel: float = 1.0
    mesh_repair: str = "auto"
    newton_tol: float = 1e-6
    output_dir: str | None = None
    vtu_every: int = 10
    checkpoint_every: int = 0
    name: str = "scene"
    overlap_tolerance: float = 1e-3

    def __repr__(self) -> str:
        on = [f.name for f in fields(self.effects) if getattr(self.effects, f.name) is True]
        fluid = ("dry" if self.fluid is None or not self.effects.fluid else
                 f"fluid rho={self.fluid.density:g} mu={self.fluid.viscosity:g}")
        return (f"Scene({self.name!r}: {len(self.particles)} particles in {self.domain}, "
                f"{fluid}, mesh {self.mesh.kind!r}, t_end={self.time.t_end:g} s "
                f"dt={self.time.dt:g} s, effects {'+'.join(on) or 'none'})")

    @property
    def moving_mesh(self) -> bool:
        """Whether the mesh moves with the particles (ALE): ``mesh_motion`` resolved."""
        if self.mesh_motion == "auto":
            return self.coupling in ("monolithic", "split")
        return self.mesh_motion == "ale"

    @property
    def repairs_mesh(self) -> bool:
        """Whether a moving mesh is repaired by edge flips before it is rebuilt
        (``mesh_repair`` resolved)."""
        if self.mesh_repair == "auto":
            return self.coupling == "split"
        return self.mesh_repair == "flips"

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
        d = vec("domain", "box", self.domain, 4)
        if not (d[2] > d[0] and d[3] > d[1]):
            raise ValueError(
                f"domain.box = {list(d)}: must be (x0, y0, x1, y1) with x1 > x0, y1 > y0"
            )
        object.__setattr__(self, "domain", d)
        object.__setattr__(self, "gravity", vec("scene", "gravity", self.gravity))
        num("domain", "wall_thickness", self.wall_thickness, lo=0)
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
            num(f"particles[{i}]", "density", p.density, lo=0)
            num(f"particles[{i}]", "core_ratio", p.core_ratio, lo=0, hi=1.0)
            vec(f"particles[{i}]", "velocity", p.velocity)
            num(f"particles[{i}]", "angular_velocity", p.angular_velocity)
            V = p.polygon.vertices
            if V[0].min() < d[0] or V[0].max() > d[2] or V[1].min() < d[1] or V[1].max() > d[3]:
                raise ValueError(f"particles[{i}]: polygon sticks out of domain.box {list(d)}")
            if p.motion is not None:
                self._check_motion(i, p)
        self._check_coupling()
        object.__setattr__(self, "newton_tol",
                           num("coupling", "newton_tol", self.newton_tol, lo=0, hi=1e-3))
        for key in ("vtu_every", "checkpoint_every"):
            v = getattr(self, key)
            if not (isinstance(v, int) and not isinstance(v, bool) and v >= 0):
                raise ValueError(f"output.{key} = {v!r}: must be an integer >= 0")
        if self.output_dir is not None and not isinstance(self.output_dir, (str, os.PathLike)):
            raise ValueError(
                f"output.directory = {self.output_dir!r}: must be a directory path (string)"
            )
        num("scene", "overlap_tolerance", self.overlap_tolerance, lo=0, hi=0.1)
        self._check_dem_dt()
        if self.fluid is None and self.effects.fluid:
            object.__setattr__(self, "effects", replace(self.effects, fluid=False))

    def _check_coupling(self) -> None:
        """The ``[coupling]`` keys but ``newton_tol`` (one-line errors)."""
        if self.coupling not in ("monolithic", "partitioned", "split"):
            raise ValueError(f"coupling.scheme = {self.coupling!r}: must be 'monolithic', "
                             "'split' or 'partitioned'")
        num("coupling", "remesh_fraction", self.remesh_fraction, lo=0, hi=1.0)
        if self.mesh_motion not in ("auto", "fixed", "ale"):
            raise ValueError(f"coupling.mesh_motion = {self.mesh_motion!r}: must be 'auto', "
                             "'ale' or 'fixed'")
        if self.mesh_motion == "ale" and self.coupling == "partitioned":
            raise ValueError("coupling.mesh_motion = 'ale': needs coupling.scheme = "
                             "'monolithic' or 'split' (the partitioned scheme runs on a "
                             "fixed mesh)")
        num("coupling", "remesh_travel", self.remesh_travel, lo=0, hi=100.0)
        if self.mesh_repair not in ("auto", "flips", "none"):
            raise ValueError(f"coupling.mesh_repair = {self.mesh_repair!r}: must be 'auto', "
                             "'flips' or 'none'")

    def _check_motion(self, i: int, p: ParticleSpec) -> None:
        """A prescribed motion fits its particle and the run (one-line errors)."""
        where = f"particles[{i}]"
        m = p.motion
        if not isinstance(m, PrescribedMotion):
            raise ValueError(f"{where}.motion = {m!r}: must be a PrescribedMotion or None")
        if m.kind == "constant" and (tuple(p.velocity) != (0.0, 0.0) or p.angular_velocity):
            if (tuple(p.velocity), p.angular_velocity) != (m.velocity, m.omega):
                raise ValueError(f"{where}.velocity = {list(p.velocity)}, angular_velocity = "
                                 f"{p.angular_velocity:g}: a particle with a constant motion "
                                 "moves at motion.velocity, motion.omega (leave them out)")
        poly = p.polygon
        radius = float(np.hypot(*(poly.vertices - poly.centroid[:, None])).max())
        m.check_start(where, (*poly.centroid, 0.0), radius)
        t0, t1 = m.span
        if t1 < self.time.t_end * (1.0 - 1e-12):
            raise ValueError(f"{where}.motion.trajectory: the table ends at t = {t1:g} s: must "
                             f"cover the run, up to time.t_end = {self.time.t_end:g} s")
        every = self.checkpoint_every
        if m.kind == "function" and isinstance(every, int) and every > 0:
            raise ValueError(f"{where}.motion.trajectory: a Python function cannot go into a "
                             f"checkpoint (output.checkpoint_every = {self.checkpoint_every}): "
                             "give a (4, n) table, or checkpoint_every = 0")

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
        """Read a scene from a TOML file (layout: :mod:`skfem_granular.scene`)."""
        path = Path(path)
        try:
            size = path.stat().st_size
            if size > MAX_SCENE_BYTES:
                raise ValueError(f"scene file {str(path)!r}: {size / 1e6:.3g} MB; at most "
                                 f"{MAX_SCENE_BYTES / 1e6:.3g} MB (a scene of "
                                 f"{MAX_PARTICLES} particles with their vertices fits)")
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
        scene = cls(name=path.stem, **scene_kwargs(data, base=path.parent))
        if scene.output_dir is not None and not Path(scene.output_dir).is_absolute():
            scene = replace(scene, output_dir=str(Path(scene.output_dir)))
        return scene

    @classmethod
    def from_dict(cls, data: dict, name: str = "scene") -> Scene:
        """Build a scene from the nested dictionary of the TOML layout."""
        return cls(name=name, **scene_kwargs(data))

    @classmethod
    def bundled(cls, name: str) -> Scene:
        """A scene shipped with the package, by name (``skfem-granular scenes`` lists them)."""
        return cls.from_toml(bundled(name))


check_table(Scene, SCENE_DOCS)  # every field is a TOML key or marked as none
