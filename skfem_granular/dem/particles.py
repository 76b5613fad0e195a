"""Particle descriptions and the array state of all particles.

:class:`Particle` is the user's description of one particle (shape, density,
initial velocity, core outline). :class:`ParticleArrays` holds everything for
all particles in arrays: reference outlines relative to the centroid (padded
to a common vertex count), mass, inertia and the state ``q = (x, y, angle)``,
``v = (vx, vy, omega)`` as ``(3, N)`` arrays. :class:`Body` is a thin view.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .motion import PrescribedMotion
from .polygon import Polygon

#: core/shadow size ratio used when a particle specifies no core
DEFAULT_CORE_RATIO = 0.8

__all__ = ["DEFAULT_CORE_RATIO", "Body", "Particle", "ParticleArrays", "pad_outlines",
           "rotate_outlines"]


@dataclass
class Particle:
    """Description of one particle.

    Parameters
    ----------
    shape
        Shadow outline (contacts, mass) as a :class:`Polygon` or ``(2, N)`` array.
    density
        Mass density ``> 0`` (mass per unit length is ``density * area``).
    velocity
        Initial velocity ``(vx, vy)`` of the centroid.
    angular_velocity
        Initial angular velocity (rad/s, counter-clockwise positive).
    core_ratio
        Core outline = shadow scaled about the centroid by this ratio in (0, 1].
    core_offset
        Alternatively, core outline = shadow offset inwards by this distance.
        With neither given, the core is the shadow scaled by
        :data:`DEFAULT_CORE_RATIO` (0.8, inside the 0.7-0.95 literature range).
    motion
        A :class:`~skfem_granular.dem.motion.PrescribedMotion`: the particle moves along
        it whatever the forces (kinematic); ``None`` (default): a free particle. A
        constant motion sets the initial velocity (leave ``velocity`` and
        ``angular_velocity`` at 0 or give the same values); a table or a function
        must start at the particle's pose at ``t = 0``.
    """

    shape: Polygon
    density: float
    velocity: tuple[float, float] = (0.0, 0.0)
    angular_velocity: float = 0.0
    core_ratio: float | None = None
    core_offset: float | None = None
    motion: PrescribedMotion | None = None


def pad_outlines(outlines: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Stack ``(2, n_k)`` outlines into ``(K, nmax, 2)``, padded with the first vertex.

    Padding with the first vertex adds zero-length edges only, so padded
    outlines describe the same polygons.
    """
    counts = np.array([o.shape[1] for o in outlines], dtype=np.int64)
    nmax = int(counts.max()) if len(outlines) else 3
    out = np.empty((len(outlines), nmax, 2))
    for k, o in enumerate(outlines):
        out[k, : o.shape[1]] = o.T
        out[k, o.shape[1] :] = o[:, 0]
    return out, counts


def rotate_outlines(local: np.ndarray, q: np.ndarray) -> np.ndarray:
    """World vertices ``X + R(angle) local`` for padded outlines.

    Parameters
    ----------
    local
        ``(N, nmax, 2)`` vertices relative to the centroids at angle 0.
    q
        ``(3, N)`` state: centroid ``x``, ``y`` and ``angle``.
    """
    c, s = np.cos(q[2])[:, None], np.sin(q[2])[:, None]
    lx, ly = local[..., 0], local[..., 1]
    out = np.empty_like(local)
    out[..., 0] = c * lx - s * ly + q[0][:, None]
    out[..., 1] = s * lx + c * ly + q[1][:, None]
    return out


def _positive(name: str, field: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}.{field} = {value!r}: must be a number > 0") from None
    if not (np.isfinite(v) and v > 0):
        raise ValueError(f"{name}.{field} = {value!r}: must be finite and > 0")
    return v


def _motion(name: str, motion, start, vel, om, radius):
    """``motion`` checked against the particle it moves (one-line errors naming it)."""
    if motion is None:
        return None
    if not isinstance(motion, PrescribedMotion):
        raise ValueError(f"{name}.motion = {motion!r}: must be a PrescribedMotion or None")
    if motion.kind == "constant" and (np.any(vel != 0) or om != 0):
        given = np.array([vel[0], vel[1], om])
        if not np.array_equal(given, motion.initial_velocity()):
            raise ValueError(f"{name}.velocity = {list(vel)}, angular_velocity = {om:g}: a "
                             "particle with a constant motion moves at its motion's velocity "
                             "(leave them out)")
    motion.check_start(name, start, radius)
    return motion


class ParticleArrays:
    """State and properties of all particles, in arrays.

    Parameters
    ----------
    particles
        Sequence of :class:`Particle`.

    Attributes
    ----------
    q, v
        ``(3, N)`` positions ``(x, y, angle)`` and velocities ``(vx, vy, omega)``.
    mass, inertia, area, density, radius
        ``(N,)`` arrays; ``radius`` is the bounding radius of the shadow.
    core_area
        ``(N,)`` areas of the cores (the outlines a fluid sees; buoyancy acts on them).
    shadow_local, core_local
        ``(N, nmax, 2)`` padded outlines relative to the centroid at angle 0;
        ``shadow_count``, ``core_count`` their true vertex counts.
    motions : list
        ``(N,)`` :class:`~skfem_granular.dem.motion.PrescribedMotion` or ``None``.
    imposed : (N,) bool ndarray
        Which particles move along a prescribed motion.
    start : (3, N) ndarray
        The poses at ``t = 0`` (where constant motions start from).
    """

    def __init__(self, particles):
        particles = list(particles)
        shadows, cores = [], []
        N = len(particles)
        self.density = np.empty(N)
        self.area = np.empty(N)
        self.core_area = np.empty(N)
        self.inertia = np.empty(N)
        self.q = np.zeros((3, N))
        self.v = np.zeros((3, N))
        self.motions = []
        for k, p in enumerate(particles):
            name = f"particles[{k}]"
            if not isinstance(p, Particle):
                raise ValueError(f"{name} = {p!r}: must be a Particle")
            shape = p.shape if isinstance(p.shape, Polygon) else Polygon(p.shape, name)
            rho = _positive(name, "density", p.density)
            try:
                vel = np.asarray(p.velocity, dtype=float).reshape(2)
                om = float(p.angular_velocity)
            except (TypeError, ValueError):
                raise ValueError(
                    f"{name}.velocity / angular_velocity: must be (vx, vy) and a number"
                ) from None
            if not (np.all(np.isfinite(vel)) and np.isfinite(om)):
                raise ValueError(f"{name}.velocity = {p.velocity}, angular_velocity = "
                                 f"{p.angular_velocity}: must be finite")
            try:
                ratio = p.core_ratio
                if ratio is None and p.core_offset is None:
                    ratio = DEFAULT_CORE_RATIO
                core = shape.core(ratio=ratio, offset=p.core_offset)
            except ValueError as err:
                raise ValueError(f"{name}.{err}") from None
            c = shape.centroid[:, None]
            shadows.append(shape.vertices - c)
            cores.append(core.vertices - c)
            self.density[k] = rho
            self.area[k] = shape.area
            self.core_area[k] = core.area
            self.inertia[k] = rho * shape.second_moment
            self.q[:2, k] = shape.centroid
            self.v[:2, k] = vel
            self.v[2, k] = om
            self.motions.append(_motion(name, p.motion, self.q[:, k], vel, om,
                                        float(np.hypot(*(shape.vertices - c)).max())))
            if p.motion is not None:
                self.v[:, k] = p.motion.initial_velocity(vel, om)
        self.imposed = np.array([m is not None for m in self.motions], dtype=bool)
        self.start = self.q.copy()
        self.mass = self.density * self.area
        self.shadow_local, self.shadow_count = pad_outlines(shadows)
        self.core_local, self.core_count = pad_outlines(cores)
        d = self.shadow_local
        self.radius = (
            np.sqrt((d * d).sum(axis=2)).max(axis=1) if N else np.zeros(0)
        )

    @property
    def n(self) -> int:
        """Number of particles."""
        return self.q.shape[1]

    def world_shadows(self, q=None) -> np.ndarray:
        """``(N, nmax, 2)`` padded shadow vertices in world coordinates."""
        return rotate_outlines(self.shadow_local, self.q if q is None else q)

    def world_cores(self, q=None) -> np.ndarray:
        """``(N, nmax, 2)`` padded core vertices in world coordinates."""
        return rotate_outlines(self.core_local, self.q if q is None else q)


class Body:
    """Thin view on particle ``index`` of a :class:`~skfem_granular.dem.DEMSystem`.

    Reading and writing the attributes reads and writes the system arrays.
    """

    def __init__(self, system, index: int):
        self._s = system
        self.index = index

    @property
    def position(self) -> np.ndarray:
        """Centroid ``(2,)`` (a view)."""
        return self._s.positions[:, self.index]

    @position.setter
    def position(self, value):
        self._s.positions[:, self.index] = value

    @property
    def angle(self) -> float:
        """Rotation angle relative to the initial outline."""
        return float(self._s.angles[self.index])

    @angle.setter
    def angle(self, value):
        self._s.angles[self.index] = value

    @property
    def velocity(self) -> np.ndarray:
        """Centroid velocity ``(2,)`` (a view)."""
        return self._s.velocities[:, self.index]

    @velocity.setter
    def velocity(self, value):
        self._s.velocities[:, self.index] = value

    @property
    def angular_velocity(self) -> float:
        """Angular velocity (rad/s)."""
        return float(self._s.angular_velocities[self.index])

    @angular_velocity.setter
    def angular_velocity(self, value):
        self._s.angular_velocities[self.index] = value

    @property
    def mass(self) -> float:
        """Mass per unit length."""
        return float(self._s.mass[self.index])

    @property
    def inertia(self) -> float:
        """Moment of inertia per unit length about the centroid."""
        return float(self._s.inertia[self.index])

    def shadow(self) -> np.ndarray:
        """``(2, n)`` shadow outline in world coordinates."""
        return self._s.shadow_outlines([self.index])[0]

    def core(self) -> np.ndarray:
        """``(2, n)`` core outline in world coordinates."""
        return self._s.core_outlines([self.index])[0]

    def point_velocity(self, points) -> np.ndarray:
        """Rigid velocity ``V + omega x (x - X)`` at ``points`` ``(2, M)``."""
        return self._s.point_velocity(self.index, points)

    def __repr__(self) -> str:
        return f"Body({self.index}, position={self.position.tolist()}, angle={self.angle:.4g})"
