"""Terminal settling velocity of a disk by steady solves in the particle's frame.

The second, independent route of the terminal-velocity check (the first is the
coupled free-settling run): the velocity ``U`` at which the steady
Navier-Stokes drag on a *fixed* disk, in a long channel whose walls and far
field move at ``U`` past it, equals the immersed weight
``(rho_p - rho_f) A g``. Nothing here depends on the moving mesh or on the
coupled stepper; only :func:`~skfem_granular.fluid.solve_steady` and
:func:`meshing.build` are used.

Boundary conditions of the frame problem
----------------------------------------
In the laboratory frame the particle falls at ``(0, -U)`` along the
centreline of a closed channel of width ``W``; the walls are at rest and so
is the fluid far above and below the particle (a closed channel carries no
net flux through any cross-section, and the disturbance of a body in a
channel decays exponentially with the distance, over a fraction of ``W``
in Stokes flow and over the wake length downstream). Subtracting the
particle's velocity gives the frame in which the particle is at rest:

- side walls ``"left"``, ``"right"``: ``u = (0, U)`` (no slip on walls
  sliding upwards at ``U``);
- upstream end ``"bottom"`` (the fluid the particle falls into): ``u = (0, U)``,
  the undisturbed far field, a plug flow that matches the walls exactly;
- downstream end ``"top"`` (the wake side): "do-nothing" outflow, so the
  wake leaves the box instead of being forced back to a plug at a finite
  distance; ``upstream``/``downstream`` lengths of several widths make the
  choice immaterial (checked: :func:`terminal_velocity_frame_solve` reports
  the drag sensitivity to the channel length on request);
- disk ``"particle0"``: ``u = 0``, no rotation: on the centreline the
  torque vanishes by symmetry, so a non-rotating disk is the free one (the
  residual torque on the discrete mesh is reported).

The drag is the consistent (reaction) force ``flow.force("particle0")``; in
this frame the fluid pushes the disk upwards, ``F_y > 0``. The Stokes limit
of the same problem is validation case 3 (Faxen), see :func:`faxen_drag_coefficient`.

The secant iteration works on ``g(U) = F_y(U) / W_b - 1`` (``W_b`` the
immersed weight) started from the Stokes estimate; every Newton solve starts
from the previous flow scaled to the new ``U``.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from ..fluid import ConvergenceError, Flow, Fluid, TaylorHood, solve_steady

__all__ = ["FrameProblem", "TerminalResult", "faxen_drag_coefficient", "frame_drag",
           "frame_mesh", "terminal_velocity_frame_solve"]


def faxen_drag_coefficient(k: float) -> float:
    """``F / (mu U)`` of a cylinder on the centreline of a closed channel (validation case 3).

    ``k = a / l`` (radius over half-width); good to better than 0.04 % for
    ``k <= 1/3``.
    """
    s = (math.log(1.0 / k) - 0.9157 + 1.7244 * k**2 - 1.7302 * k**4 + 2.4056 * k**6
         - 4.5913 * k**8)
    return 4.0 * math.pi / s


@dataclass(frozen=True)
class FrameProblem:
    """A disk on the centreline of a long channel, seen from the disk (SI units).

    Attributes
    ----------
    width : float
        Channel width ``W`` (m).
    radius : float
        Circumradius of the regular ``sides``-gon outline (m).
    sides : int
        Outline vertices (the coupled run's polygon).
    rho_p, rho_f, mu, g : float
        Particle and fluid density, viscosity, gravity (all > 0).
    upstream, downstream : float
        Channel length below (inflow) and above (outflow) the disk centre (m).
    delta_l, sigma : float or None
        Mesh options of :func:`meshing.build` (``"graded"``), as in the scene.
    angle : float
        Outline rotation (rad), as the scene's polygon.
    """

    width: float
    radius: float
    sides: int
    rho_p: float
    rho_f: float
    mu: float
    g: float = 9.81
    upstream: float | None = None
    downstream: float | None = None
    delta_l: float | None = None
    sigma: float | None = None
    angle: float = 0.0

    def __post_init__(self):
        for name in ("width", "radius", "rho_p", "rho_f", "mu", "g"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"FrameProblem.{name} = {v!r}: must be a finite number > 0")
        if not 2 * self.radius < self.width:
            raise ValueError(f"FrameProblem.radius = {self.radius!r}: the disk must fit the "
                             f"channel (2 radius < width = {self.width!r})")
        if self.rho_p <= self.rho_f:
            raise ValueError(f"FrameProblem.rho_p = {self.rho_p!r}: must exceed rho_f = "
                             f"{self.rho_f!r} (a settling particle)")
        if self.upstream is None:
            object.__setattr__(self, "upstream", 5.0 * self.width)
        if self.downstream is None:
            object.__setattr__(self, "downstream", 10.0 * self.width)

    @property
    def area(self) -> float:
        """Area of the regular polygon (the particle's mass and buoyancy use it)."""
        n = self.sides
        return 0.5 * n * self.radius**2 * math.sin(2.0 * math.pi / n)

    @property
    def weight(self) -> float:
        """Immersed weight per unit length ``(rho_p - rho_f) A g`` (N/m)."""
        return (self.rho_p - self.rho_f) * self.area * self.g

    @property
    def area_radius(self) -> float:
        """Radius of the circle with the polygon's area."""
        return math.sqrt(self.area / math.pi)

    @property
    def k(self) -> float:
        """Confinement ``a / (W / 2)`` with the area radius."""
        return 2.0 * self.area_radius / self.width

    @property
    def fluid(self) -> Fluid:
        return Fluid(self.rho_f, self.mu)

    @property
    def stokes_estimate(self) -> float:
        """Faxen's Stokes-limit terminal velocity ``W_b / (mu F/(mu U))`` (an upper bound)."""
        return self.weight / (self.mu * faxen_drag_coefficient(self.k))

    def reynolds(self, U: float) -> float:
        """Particle Reynolds number ``rho_f U d / mu`` (``d`` twice the circumradius)."""
        return self.rho_f * U * 2.0 * self.radius / self.mu

    @classmethod
    def from_scene(cls, scene, **overrides) -> FrameProblem:
        """The frame problem of a scene with one regular polygon in a rectangular box.

        Width from ``scene.domain``, outline (sides, circumradius, angle) from
        the particle's *core* (the outline the fluid sees), the particle density
        per core area (a scene's density applies to the shadow: the mass is
        ``density x shadow area``, so ``rho_p = density / core_ratio^2``), fluid
        density and viscosity from the scene, ``g = |gravity|``,
        mesh ``delta_l`` and ``sigma`` from ``scene.mesh`` (a graded mesh is built
        whatever the scene's kind, to keep the resolution at the particle).
        """
        if len(scene.particles) != 1 or scene.fluid is None:
            raise ValueError(f"scene {scene.name!r}: needs exactly one particle and a fluid")
        p = scene.particles[0]
        V = p.polygon.vertices
        c = V.mean(axis=1)
        r = np.hypot(*(V - c[:, None]))
        if np.ptp(r) > 1e-9 * r.max():
            raise ValueError(f"scene {scene.name!r}: the particle must be a regular polygon")
        x0, _, x1, _ = scene.domain
        kw = dict(width=float(x1 - x0), radius=float(r.mean() * p.core_ratio),
                  sides=int(V.shape[1]), rho_p=float(p.density) / p.core_ratio**2,
                  rho_f=float(scene.fluid.density), mu=float(scene.fluid.viscosity),
                  g=float(np.hypot(*scene.gravity)), delta_l=scene.mesh.delta_l,
                  sigma=scene.mesh.sigma,
                  angle=float(np.arctan2(V[1, 0] - c[1], V[0, 0] - c[0])))
        kw.update(overrides)
        return cls(**kw)


def frame_mesh(problem: FrameProblem):
    """Graded mesh of the frame problem: a :class:`meshing.BodyFittedMesh`.

    Channel ``[0, W] x [0, upstream + downstream]`` with the disk centre at
    ``(W/2, upstream)``; boundaries ``"left"``, ``"right"``, ``"bottom"``,
    ``"top"``, ``"particle0"``.
    """
    import meshing

    from ..dem import Polygon

    W, up, down = problem.width, problem.upstream, problem.downstream
    assert up is not None and down is not None  # set by FrameProblem.__post_init__
    disk = Polygon.regular(problem.sides, problem.radius, center=(0.5 * W, up),
                           angle=problem.angle).vertices
    return meshing.build("graded", (0.0, 0.0, W, up + down), [disk],
                         sigma=problem.sigma, delta_l=problem.delta_l)


def frame_drag(space: TaylorHood, fluid: Fluid, U: float, *, convection: bool = True,
               initial=None, tol: float = 1e-11, maxiter: int = 25):
    """Steady flow past the fixed disk with walls and inflow at ``(0, U)``.

    Returns
    -------
    (force, torque, flow)
        ``force`` ``(2,)`` on ``"particle0"`` (consistent force), the torque about
        the boundary centroid, and the :class:`~skfem_granular.fluid.Flow`.
    """
    bc = {"left": (0.0, U), "right": (0.0, U), "bottom": (0.0, U), "particle0": (0.0, 0.0)}
    flow = solve_steady(space, fluid, bc, convection=convection, initial=initial, tol=tol,
                        maxiter=maxiter)
    return flow.force("particle0"), flow.torque("particle0"), flow


@dataclass
class TerminalResult:
    """What :func:`terminal_velocity_frame_solve` found (SI units).

    ``U`` the terminal velocity, ``residual`` ``F_y(U) / W_b - 1`` at it,
    ``iterations`` steady solves, ``history`` ``[(U, F_y), ...]``,
    ``reynolds`` ``rho_f U d / mu``, ``lift`` and ``torque`` the residual
    sideways force and torque (symmetry: both ~0), ``mesh`` sizes,
    ``wall_time`` seconds, ``stokes`` ``F/(mu U)`` of the Stokes solve and
    Faxen's value at the area radius.
    """

    U: float
    residual: float
    iterations: int
    converged: bool
    weight: float
    reynolds: float
    lift: float
    torque: float
    history: list = field(default_factory=list)
    mesh: dict = field(default_factory=dict)
    stokes: dict = field(default_factory=dict)
    problem: dict = field(default_factory=dict)
    wall_time: float = 0.0

    def as_dict(self) -> dict:
        return asdict(self)


def terminal_velocity_frame_solve(problem, *, rtol: float = 1e-6, maxiter: int = 30,
                                  U0: float | None = None, mesh=None,
                                  **overrides) -> TerminalResult:
    """Terminal velocity ``U`` with ``F_y(U) = (rho_p - rho_f) A g`` (secant iteration).

    Parameters
    ----------
    problem : FrameProblem or Scene
        A scene is turned into a problem with :meth:`FrameProblem.from_scene`
        (``overrides`` are passed on: ``upstream``, ``downstream``, ``delta_l``...).
    rtol : float
        Stop when ``|F_y(U) / W_b - 1| < rtol``.
    maxiter : int
        Most steady Navier-Stokes solves.
    U0 : float, optional
        First guess (default: 0.5 x the Stokes estimate, which always
        overestimates the inertial terminal velocity).
    mesh : meshing.BodyFittedMesh or skfem.MeshTri, optional
        Reuse a mesh of :func:`frame_mesh`.

    Returns
    -------
    TerminalResult
        ``converged`` False (and the last iterate) when ``maxiter`` solves did
        not reach ``rtol``.
    """
    t0 = time.perf_counter()
    if not isinstance(problem, FrameProblem):
        problem = FrameProblem.from_scene(problem, **overrides)
    elif overrides:
        from dataclasses import replace

        problem = replace(problem, **overrides)
    value = frame_mesh(problem) if mesh is None else mesh
    m = getattr(value, "mesh", value)
    space = TaylorHood(m)
    fluid = problem.fluid
    Wb = problem.weight
    # Stokes drag coefficient on this mesh (linear in U: one solve at U = 1)
    Fs, _, _ = frame_drag(space, fluid, 1.0, convection=False)
    cs = Fs[1] / problem.mu
    stokes = {"F_over_muU": float(cs), "faxen_area_radius": faxen_drag_coefficient(problem.k),
              "rel_error": float(cs / faxen_drag_coefficient(problem.k) - 1.0)}
    Us = Wb / problem.mu / cs
    history = []
    # (U, flow) of converged Navier-Stokes solves, for continuation
    solved: list[tuple[float, Flow]] = []

    def solve(U, depth=0):
        """Navier-Stokes at ``U`` from the nearest converged flow (scaled to ``U``);
        on a Newton failure, continuation through the midpoint speed first."""
        if solved:
            Uc, fc = min(solved, key=lambda s: abs(s[0] - U))
            init = fc.x * (U / Uc)
        else:
            Uc, init = 0.0, None
        try:
            out = frame_drag(space, fluid, U, initial=init)
        except ConvergenceError:
            if depth >= 12:
                raise
            solve(Uc + 0.5 * (U - Uc) if solved else 0.5 * U, depth + 1)
            return solve(U, depth + 1)
        solved.append((U, out[2]))
        return out

    def g(U):
        F, T, _ = solve(U)
        history.append((float(U), float(F[1]), float(F[0]), float(T)))
        return F[1] / Wb - 1.0

    U_a = 0.5 * Us if U0 is None else float(U0)
    g_a = g(U_a)
    # second point: the drag grows at least linearly, so U (1 - g)/(1 + g)-ish; use
    # the Stokes-like scaling U / (1 + g)
    U_b = U_a / (1.0 + g_a)
    g_b = g(U_b)
    it = 2
    while abs(g_b) >= rtol and it < maxiter:
        dg = g_b - g_a
        U_new = U_b - g_b * (U_b - U_a) / dg if dg != 0 else U_b / (1.0 + g_b)
        if not (np.isfinite(U_new) and U_new > 0):
            U_new = U_b / (1.0 + g_b)
        U_a, g_a = U_b, g_b
        U_b, g_b = U_new, g(U_new)
        it += 1
    last = history[-1]
    from meshing import mesh_stats

    st = mesh_stats(m)
    return TerminalResult(
        U=float(U_b), residual=float(g_b), iterations=it, converged=bool(abs(g_b) < rtol),
        weight=float(Wb), reynolds=problem.reynolds(U_b), lift=last[2], torque=last[3],
        history=[list(h) for h in history],
        mesh={"vertices": int(st.n_vertices), "p2_nodes": int(st.n_p2_nodes),
              "triangles": int(st.n_triangles), "dofs": int(space.N),
              "min_angle": float(st.min_angle)},
        stokes=stokes, problem=asdict(problem), wall_time=time.perf_counter() - t0)
