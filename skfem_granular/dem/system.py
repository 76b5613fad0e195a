"""DEMSystem: particles, walls, contact law and the time-stepping loop."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from . import overlap_numba, pipeline, snapshot, start_checks, substeps_numba
from .broadphase import NeighbourList, circle_pairs, wall_pairs
from .contact_law import ContactForces, ContactHistory, ContactLaw
from .integrator import BDF2History, correct, predict, stable_time_step
from .motion import pose_derivative
from .particles import Body, ParticleArrays, rotate_outlines
from .snapshot import DEMSnapshot
from .walls import WallArrays, box_walls

__all__ = ["MAX_STEP_RATIO", "DEMSystem"]

#: larger step growth restarts BDF2 with its one-step start (zero stability: w < 1 + sqrt 2)
MAX_STEP_RATIO = 2.0

#: :meth:`DEMSystem.contact_possible` grows each particle's reach over a step by this
#: factor on ``|v| dt + a dt^2``.
CONTACT_TRAVEL_SAFETY = 3.0


def _repad(V: np.ndarray, nmax: int) -> np.ndarray:
    """Pad ``(K, n, 2)`` outlines to ``nmax`` vertices by repeating vertex 0."""
    if V.shape[1] >= nmax:
        return V
    pad = np.repeat(V[:, :1], nmax - V.shape[1], axis=1)
    return np.concatenate([V, pad], axis=1)


class DEMSystem:
    """A dry (or fluid-forced) 2D DEM of convex polygons and fixed walls.

    Parameters
    ----------
    particles
        Sequence of :class:`~skfem_granular.dem.Particle`.
    walls
        Sequence of :class:`~skfem_granular.dem.Polygon` (or ``(2, n)`` arrays).
    law
        :class:`~skfem_granular.dem.ContactLaw` (E, mu, gamma, ...).
    gravity
        Gravitational acceleration ``(gx, gy)``.
    fluid_density
        ``rho_f``: gravity acts as ``(rho_p A - rho_f A_core) g`` (0 for dry scenes):
        the buoyancy of the core, the outline a fluid sees, as in coupled runs.
    domain
        Optional box ``(x0, y0, x1, y1)`` every particle must lie inside.
    dt
        Default step for :meth:`step` / maximal substep of :meth:`advance`;
        ``None`` means the stable estimate :attr:`dt_stable`.
    overlap_tolerance
        Allowed initial overlap area relative to the smaller particle.
    margin
        Verlet skin; default a fifth of the mean bounding radius.
    backend
        ``"numba"``, ``"numpy"`` or ``"auto"`` (numba if installed).

    Attributes
    ----------
    positions, velocities
        ``(2, N)`` views of the state (centroids); ``angles``,
        ``angular_velocities`` ``(N,)`` views.
    mass, inertia
        ``(N,)`` mass and moment of inertia per unit length.
    external_force, external_torque
        ``(2, N)`` and ``(N,)`` forces held constant during a step (the fluid
        coupling writes here); ``force_callbacks`` is a list of
        ``f(system, t) -> (F (2, N), T (N,))`` evaluated every force evaluation.
    force, torque
        Total force and torque of the last evaluation.
    contacts
        :class:`~skfem_granular.dem.contact_law.ContactForces` of the last step.
    imposed
        ``(N,)`` bool: the particles with a prescribed motion
        (:class:`~skfem_granular.dem.motion.PrescribedMotion`). They move along it
        whatever the forces: each step puts them at the motion's pose, with the BDF2
        derivative of their poses as velocity (:func:`~skfem_granular.dem.motion.pose_derivative`);
        for the others they are moving walls.

    Notes
    -----
    Units are SI per unit length in z: mass ``density * area`` (kg/m), ``E``
    such that ``E A / L`` is a force per unit length. One :meth:`step` runs
    the pipeline of :mod:`.pipeline` once at the BDF2-predicted state. After
    setting positions or velocities by hand call :meth:`reset_history`;
    :meth:`save_state` / :meth:`restore_state` carry everything needed for a
    bitwise-identical continuation (state, BDF2 history, contact springs,
    external forces). Without ``domain`` no containment check is made (open
    scenes are allowed).

    Examples
    --------
    >>> from skfem_granular.dem import DEMSystem, Particle, Polygon
    >>> grain = Particle(Polygon.regular(6, 0.4e-3, center=(1.5e-3, 0.5e-3)), 2650.0)
    >>> dem = DEMSystem.in_box([grain], (0.0, 0.0, 3e-3, 11e-3), wall_thickness=0.5e-3)
    >>> n = dem.advance(1e-4)              # substeps of at most dem.dt_stable
    >>> dem.external_force[:, 0] = (0.0, 1e-3)   # e.g. a hydrodynamic force
    >>> outline = dem.core_outlines()[0]   # (2, 6) counter-clockwise, for the mesh
    """

    def __init__(self, particles, walls=(), *, law: ContactLaw | None = None,
                 gravity=(0.0, -9.81), fluid_density: float = 0.0, domain=None,
                 dt: float | None = None, overlap_tolerance: float = 1e-3,
                 margin: float | None = None, backend: str = "auto"):
        self.particles = ParticleArrays(particles)
        self.walls = WallArrays(walls)
        self.law = ContactLaw() if law is None else law
        if not isinstance(self.law, ContactLaw):
            raise ValueError(f"law = {law!r}: must be a ContactLaw")
        self.gravity = np.asarray(gravity, dtype=float).reshape(2)
        if not np.all(np.isfinite(self.gravity)):
            raise ValueError(f"gravity = {gravity}: must be finite")
        if not (np.isfinite(fluid_density) and fluid_density >= 0):
            raise ValueError(f"fluid_density = {fluid_density}: must be finite and >= 0")
        self.fluid_density = float(fluid_density)
        if backend == "auto":
            backend = "numba" if overlap_numba.AVAILABLE else "numpy"
        if backend not in ("numba", "numpy") or (backend == "numba"
                                                  and not overlap_numba.AVAILABLE):
            raise ValueError(f"backend = {backend!r}: must be 'numpy', 'auto' or "
                             "'numba' (numba installed)")
        self.backend = backend
        p = self.particles
        N = p.n
        nmax = max(p.shadow_local.shape[1], self.walls.vertices.shape[1])
        self._shadow_local = _repad(p.shadow_local, nmax)
        self._wall_vertices = _repad(self.walls.vertices, nmax)
        self._count = np.concatenate([p.shadow_count, self.walls.count]).astype(np.int64)
        self.positions = p.q[:2]
        self.imposed = p.imposed
        self.angles = p.q[2]
        self.velocities = p.v[:2]
        self.angular_velocities = p.v[2]
        self.mass = p.mass
        self.inertia = p.inertia
        self.external_force = np.zeros((2, N))
        self.external_torque = np.zeros(N)
        self.force_callbacks: list[Callable[[DEMSystem, float], tuple[ArrayLike, ArrayLike]]] = []
        self.force = np.zeros((2, N))
        self.torque = np.zeros(N)
        self.t = 0.0
        self.steps = 0
        self.bdf2 = BDF2History()
        self.contact_history = ContactHistory()
        if margin is None:
            margin = 0.2 * float(p.radius.mean()) if N else 0.0
        self.neighbours = NeighbourList(margin)
        self.contacts: ContactForces | None = None
        self.dt_stable = stable_time_step(self.mass, self.law.E, self.law.gamma)
        self.dt = self._check_dt(self.dt_stable if dt is None else dt, "dt")
        self.domain = None if domain is None else tuple(float(x) for x in domain)
        start_checks.check_domain(self)
        start_checks.check_overlaps(self, overlap_tolerance)

    # ------------------------------------------------------------------ setup
    @classmethod
    def in_box(cls, particles, box: tuple[float, float, float, float], wall_thickness: float,
               **kwargs) -> DEMSystem:
        """System with :func:`~skfem_granular.dem.box_walls` around ``box = (x0, y0, x1, y1)``."""
        walls = box_walls(*box, wall_thickness) + list(kwargs.pop("walls", []))
        return cls(particles, walls, domain=box, **kwargs)

    @property
    def n(self) -> int:
        """Number of particles."""
        return self.particles.n

    def __repr__(self) -> str:
        contacts = 0 if self.contacts is None else int(self.contacts.i.size)
        return (f"DEMSystem({self.n} particles, {self.walls.n} walls, t={self.t:.6g} s after "
                f"{self.steps} steps of dt<={self.dt:.3g} s, {contacts} contacts)")

    @property
    def bodies(self) -> list[Body]:
        """Thin views on the particles."""
        return [Body(self, k) for k in range(self.n)]

    def _check_dt(self, dt, field: str = "dt") -> float:
        try:
            dt = float(dt)
        except (TypeError, ValueError):
            raise ValueError(f"{field} = {dt!r}: must be a number > 0") from None
        bound = self.dt_stable
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"{field} = {dt!r}: must be finite and > 0")
        if dt > bound * (1.0 + 1e-9):
            k = int(np.argmin(self.mass))
            raise ValueError(
                f"{field} = {dt:.6g}: must be <= {bound:.6g} s, the stable step "
                f"0.1*pi*sqrt(min m / E) / max(1, 2 gamma) (min m = {self.mass[k]:.6g} of "
                f"particles[{k}], E = {self.law.E:.6g}, gamma = {self.law.gamma:g})")
        return dt

    # ------------------------------------------------------------ geometry
    def body_centroids(self, q=None) -> np.ndarray:
        """``(2, N + W)`` centroids of particles then walls."""
        q = self.particles.q if q is None else q
        return np.concatenate([q[:2], self.walls.centroid], axis=1)

    def _outlines(self, local, count, indices):
        idx = np.arange(self.n) if indices is None else np.asarray(indices, dtype=int)
        V = rotate_outlines(local[idx], self.particles.q[:, idx])
        return [V[k, : count[i]].T.copy() for k, i in enumerate(idx)]

    def shadow_outlines(self, indices=None) -> list[np.ndarray]:
        """World shadow outlines (contacts): list of ``(2, n)`` ccw arrays."""
        return self._outlines(self.particles.shadow_local, self.particles.shadow_count, indices)

    def core_outlines(self, indices=None) -> list[np.ndarray]:
        """World core outlines (the fluid boundary): list of ``(2, n)`` ccw arrays."""
        return self._outlines(self.particles.core_local, self.particles.core_count, indices)

    def wall_outlines(self) -> list[np.ndarray]:
        """Wall outlines (the same for contacts and fluid)."""
        return self.walls.outlines()

    def point_velocity(self, i: int, points) -> np.ndarray:
        """Rigid velocity ``V_i + omega_i x (x - X_i)`` at ``points`` ``(2, M)``."""
        x = np.asarray(points, dtype=float)
        d = x - self.positions[:, i].reshape(2, *([1] * (x.ndim - 1)))
        w = self.angular_velocities[i]
        return np.stack([self.velocities[0, i] - w * d[1], self.velocities[1, i] + w * d[0]])

    # ------------------------------------------------------------ dynamics
    def evaluate(self, q, v, t: float, dt: float):
        """Run the force pipeline at state ``(q, v)``; return ``(a (3, N), contacts)``."""
        F, T = pipeline.reset_forces(self, t)
        I, J = pipeline.broad_phase(self, q)
        V = pipeline.body_vertices(self, q)
        I, J, area, point, normal, length = pipeline.contact_geometry(self, V, q, I, J)
        cf = pipeline.apply_contact_law(self, I, J, area, point, normal, length, q, v, dt)
        pipeline.accumulate(self, cf, q, F, T)
        self.force, self.torque = F, T
        a = np.empty_like(q)
        a[:2] = F / self.mass
        a[2] = T / self.inertia
        return a, cf

    def prescribed_poses(self, t: float) -> np.ndarray:
        """Poses ``(3, N)`` of the particles with a prescribed motion at time ``t``
        (the other columns hold the current poses)."""
        p = self.particles
        q = p.q.copy()
        for k in np.flatnonzero(self.imposed):
            q[:, k] = p.motions[k].pose(t, p.start[:, k])
        return q

    def reset_history(self) -> None:
        """Forget the BDF2 history (call after changing positions/velocities by hand)."""
        self.bdf2 = BDF2History()

    def set_motion(self, q: np.ndarray, v: np.ndarray, t: float) -> None:
        """Impose poses ``q`` and velocities ``v`` (both ``(3, N)``: x, y, angle) at time ``t``.

        For a solver outside the DEM that computed the particles' motion (a coupled
        fluid-particle step); the DEM's own BDF2 history is forgotten.
        """
        self.particles.q[...] = q
        self.particles.v[...] = v
        self.t = float(t)
        self.reset_history()

    def step(self, dt: float | None = None) -> None:
        """One BDF2 predictor-corrector step of size ``dt`` (default :attr:`dt`)."""
        dt = self.dt if dt is None else self._check_dt(dt)
        p = self.particles
        h = self.bdf2
        if h.dt_prev is not None and dt / h.dt_prev > MAX_STEP_RATIO:
            # variable-step BDF2 is zero-stable only for w < 1 + sqrt(2): restart
            h.q_prev = h.v_prev = h.a_prev = h.dt_prev = None
        if self.bdf2.a is None:
            self.bdf2.a, self.contacts = self.evaluate(p.q, p.v, self.t, 0.0)
        qp, vp = predict(p.q, p.v, self.bdf2, dt)
        imposed = self.imposed
        if imposed.any():  # kinematic particles: where their motion puts them
            q_imp = self.prescribed_poses(self.t + dt)
            v_imp = pose_derivative(q_imp, p.q, h.q_prev, dt,
                                    h.dt_prev if h.q_prev is not None else None)
            qp[:, imposed], vp[:, imposed] = q_imp[:, imposed], v_imp[:, imposed]
        a, cf = self.evaluate(qp, vp, self.t + dt, dt)
        q_new, v_new = correct(p.q, p.v, self.bdf2, a, dt)
        if imposed.any():
            q_new[:, imposed], v_new[:, imposed] = q_imp[:, imposed], v_imp[:, imposed]
        p.q[...] = q_new
        p.v[...] = v_new
        self.contact_history.replace(cf.keys, cf.ft_spring, cf.mr_spring)
        self.contacts = cf
        self.t += dt
        self.steps += 1

    def contact_possible(self, dt: float, acceleration: float = 0.0) -> bool:
        """Whether two shadows, or a shadow and a wall, could touch within ``dt``.

        Conservative: a contact is open (or a tangential spring held), or the bounding
        circles grown by :data:`CONTACT_TRAVEL_SAFETY` times how far a particle can
        travel in ``dt`` (``|v| dt + acceleration dt^2``) plus a tenth of the smallest
        bounding radius meet each other or a wall. A coupled solver skips the DEM's
        substeps over a step when this is False.

        Parameters
        ----------
        dt : float
            The step ahead (s).
        acceleration : float
            A bound on the particles' accelerations over the step (m/s^2), e.g. that
            of gravity.
        """
        if self.contacts is not None and self.contacts.i.size:
            return True
        if len(self.contact_history.keys):
            return True
        q, v = self.particles.q, self.particles.v
        speed = np.hypot(v[0], v[1])
        radius = self.particles.radius
        travel = (CONTACT_TRAVEL_SAFETY * (speed * dt + abs(acceleration) * dt * dt)
                  + 0.1 * float(radius.min()))
        i, _ = circle_pairs(q[:2], radius, margin=2.0 * float(travel.max()))
        if i.size:
            return True
        i, _ = wall_pairs(q[:2], radius, self.walls.vertices, margin=float(travel.max()))
        return bool(i.size)

    def advance(self, dt_outer: float, max_substep: float | None = None) -> int:
        """Advance by ``dt_outer`` in ``n`` equal substeps ``<= max_substep``.

        ``max_substep`` defaults to :attr:`dt`. External forces are held
        during the substeps. Returns ``n``.
        """
        if not (np.isfinite(dt_outer) and dt_outer > 0):
            raise ValueError(f"dt_outer = {dt_outer!r}: must be finite and > 0")
        h = self.dt if max_substep is None else self._check_dt(max_substep, "max_substep")
        n = max(1, math.ceil(dt_outer / h * (1.0 - 1e-12)))
        dt = self._check_dt(dt_outer / n)
        done = 0
        while done < n:
            if self._compiled_ready(dt):
                k = self._compiled_substeps(n - done, dt)
                done += k
                if done == n:
                    break
            self.step(dt)  # the first of a restart, a Verlet rebuild, or the numpy path
            done += 1
        return n

    def _compiled_ready(self, dt: float) -> bool:
        """Whether the compiled substep loop can take the next substeps."""
        h = self.bdf2
        return (self.backend == "numba" and self.n > 0 and not self.force_callbacks
                and not self.imposed.any() and h.a_prev is not None
                and h.q_prev is not None and h.dt_prev is not None
                and dt / h.dt_prev <= MAX_STEP_RATIO and self.neighbours.reference is not None
                and self.neighbours.reference.shape == (2, self.n))

    def _compiled_substeps(self, n: int, dt: float) -> int:
        """Up to ``n`` substeps in :mod:`.substeps_numba`; returns how many were done."""
        p = self.particles
        F0, T0 = pipeline.reset_forces(self, self.t)
        # the walls' rows; the kernel writes the particles' at every substep
        V = np.concatenate([np.empty_like(self._shadow_local), self._wall_vertices])
        nb = self.neighbours
        done, c, F, T = substeps_numba.run_substeps(
            n, dt, p.q, p.v, self.bdf2, F0, T0, self.mass, self.inertia, p.radius,
            self._shadow_local, self._count, V, self.walls.centroid, nb.pairs, nb.reference,
            nb.margin, self.contact_history, self.law)
        if done:
            cf = ContactForces(*c[:9])
            cf.keys, cf.mr, cf.mr_spring = c[9:]
            self.contacts = cf
            self.force, self.torque = F, T
            for _ in range(done):
                self.t += dt
            self.steps += done
        return done

    # ------------------------------------------------------------ diagnostics
    def kinetic_energy(self) -> float:
        """Total translational plus rotational kinetic energy."""
        v = self.particles.v
        return float(0.5 * (self.mass * (v[0] ** 2 + v[1] ** 2)).sum()
                     + 0.5 * (self.inertia * v[2] ** 2).sum())

    def elastic_energy(self) -> float:
        """Elastic energy estimate of the current contacts (see ContactForces)."""
        return 0.0 if self.contacts is None else float(self.contacts.energy.sum())

    def contact_count(self) -> np.ndarray:
        """``(N,)`` number of contacts of every particle (last step)."""
        c = np.zeros(self.n, dtype=np.int64)
        if self.contacts is not None and self.contacts.i.size:
            c += np.bincount(self.contacts.i, minlength=self.n)
            j = self.contacts.j[self.contacts.j < self.n]
            c += np.bincount(j, minlength=self.n)
        return c

    def momentum(self) -> tuple[np.ndarray, float]:
        """Linear momentum ``(2,)`` and angular momentum about the origin."""
        v, q = self.particles.v, self.particles.q
        P = (self.mass * v[:2]).sum(axis=1)
        Lz = float((self.mass * (q[0] * v[1] - q[1] * v[0]) + self.inertia * v[2]).sum())
        return P, Lz

    # ------------------------------------------------------------ checkpoints
    def snapshot(self) -> DEMSnapshot:
        """An in-memory copy of the dynamic state, neighbour list and last contacts
        included (:func:`~skfem_granular.dem.snapshot.take`): :meth:`restore_snapshot`
        makes the system go on exactly as from the moment it was taken."""
        return snapshot.take(self)

    def restore_snapshot(self, snap: DEMSnapshot) -> None:
        """Return to the state of a :meth:`snapshot`."""
        snapshot.restore(self, snap)

    def save_state(self) -> dict:
        """Copy of the full dynamic state (positions, velocities, BDF2 and contact history;
        the rolling springs' torques only with rolling resistance)."""
        return {
            "t": self.t, "steps": self.steps,
            "q": self.particles.q.copy(), "v": self.particles.v.copy(),
            "bdf2": self.bdf2.as_dict(),
            "contact_keys": self.contact_history.keys.copy(),
            "contact_ft": self.contact_history.ft.copy(),
            "external_force": self.external_force.copy(),
            "external_torque": self.external_torque.copy(),
        } | ({"contact_mr": self.contact_history.mr.copy()} if self.law.rolls else {})

    def restore_state(self, state: dict) -> None:
        """Restore a state from :meth:`save_state` (arrays are copied in place)."""
        if state["q"].shape != self.particles.q.shape:
            raise ValueError(f"state q has shape {state['q'].shape}: must be "
                             f"{self.particles.q.shape} (same particles)")
        self.t = float(state["t"])
        self.steps = int(state["steps"])
        self.particles.q[...] = state["q"]
        self.particles.v[...] = state["v"]
        self.bdf2 = BDF2History.from_dict(state["bdf2"])
        self.contact_history = ContactHistory()
        self.contact_history.keys = np.array(state["contact_keys"], dtype=np.int64)
        self.contact_history.ft = np.array(state["contact_ft"], dtype=float)
        self.contact_history.mr = np.array(state.get("contact_mr", ()), dtype=float)
        self.external_force[...] = state["external_force"]
        self.external_torque[...] = state["external_torque"]
        self.neighbours.invalidate()
        self.contacts = None

