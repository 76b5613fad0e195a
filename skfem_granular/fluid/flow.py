"""The result of a fluid solve: fields, forces, point values and output."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from . import forces
from .points import PointLocator, evaluation_matrix


@dataclass
class SolveReport:
    """How a solve went.

    Attributes
    ----------
    iterations : int
        Newton (or fixed-point) iterations; 1 for a linear solve.
    residuals : list of float
        Relative residual norm after each iteration.
    solver : dict
        Linear solver statistics.
    wall_time : dict
        Seconds spent per phase (``assembly``, ``solve``, ...).
    continuation : list of dict
        The viscosity continuation that reached the solution, one entry per stage
        (``factor``, ``iterations``, ``converged``); empty when Newton converged
        directly.
    """

    iterations: int = 0
    residuals: list = field(default_factory=list)
    solver: dict = field(default_factory=dict)
    wall_time: dict = field(default_factory=dict)
    continuation: list = field(default_factory=list)


@dataclass
class StepInfo:
    """What one accepted step did."""

    t: float
    dt: float
    iterations: int
    error: float | None
    rejected: int = 0
    refreshes: int = 0  # Newton Jacobians factorised where the chord iteration stalled
    wall_time: dict = field(default_factory=dict)


class Flow:
    """Velocity and pressure on a mesh, with forces, point values and output.

    Parameters
    ----------
    operator : NavierStokesOperator
        The operator the state solves.
    x : ndarray
        ``[u, p]``.
    residual_u : callable
        Returns the full momentum residual (Dirichlet rows included) used
        for the consistent force.
    t : float, optional
        Time of the state (unsteady runs).
    report : SolveReport, optional
    """

    #: What the time step that reached this state did: set on the flows
    #: :func:`~skfem_granular.fluid.unsteady.evolve` yields (absent otherwise).
    step: StepInfo

    def __init__(self, operator, x: np.ndarray, residual_u, t: float | None = None,
                 report: SolveReport | None = None):
        self.operator = operator
        self.space = operator.space
        self.fluid = operator.fluid
        self.mesh = self.space.mesh
        self.x = x
        self.t = t
        self.report = report or SolveReport()
        self._residual_fn = residual_u

    @property
    def u(self) -> np.ndarray:
        """Velocity DOFs (interleaved x, y per P2 node)."""
        return self.x[: self.space.nu]

    @property
    def p(self) -> np.ndarray:
        """Pressure DOFs (P1, dynamic pressure)."""
        return self.x[self.space.nu:]

    @cached_property
    def residual_u(self) -> np.ndarray:
        """Momentum residual including the Dirichlet rows."""
        return self._residual_fn(self.x)

    def _check_method(self, method):
        if method not in ("consistent", "traction"):
            raise ValueError(f"method = {method!r}: must be 'consistent' or 'traction'")

    def force(self, name: str, method: str = "consistent") -> np.ndarray:
        """Force ``(Fx, Fy)`` of the fluid on boundary ``name`` (N per unit depth).

        Parameters
        ----------
        name : str
            A named boundary, e.g. ``"particle0"``.
        method : {"consistent", "traction"}
            Residual (reaction) force or traction integral (paper Eq. 3).
        """
        self._check_method(method)
        if method == "consistent":
            return forces.consistent_force(self.space, self.residual_u, name)
        return forces.traction_force(self.space, self.fluid, self.u, self.p, name)

    def torque(self, name: str, center=None, method: str = "consistent") -> float:
        """Torque of the fluid on boundary ``name`` about ``center``.

        ``center`` defaults to the length-weighted centroid of the boundary,
        which is the centre of a regular polygon.
        """
        self._check_method(method)
        if center is None:
            center = self.boundary_centroid(name)
        if method == "consistent":
            return forces.consistent_torque(self.space, self.residual_u, name, center)
        return forces.traction_torque(self.space, self.fluid, self.u, self.p, name, center)

    def boundary_centroid(self, name: str) -> np.ndarray:
        """Length-weighted centroid of the facets of boundary ``name``."""
        self.space.check_boundary(name, "boundary")
        f = self.mesh.facets[:, self.mesh.boundaries[name]]
        a, b = self.mesh.p[:, f[0]], self.mesh.p[:, f[1]]
        w = np.linalg.norm(b - a, axis=0)
        return ((a + b) / 2 * w).sum(axis=1) / w.sum()

    # point values -----------------------------------------------------------
    @cached_property
    def locator(self) -> PointLocator:
        """Point locator of the mesh."""
        return PointLocator(self.mesh)

    def velocity(self, points, tol: float = 1e-6) -> np.ndarray:
        """Velocity ``(2, n)`` at ``points`` ``(2, n)``."""
        cells, X = self.locator.locate(points, tol=tol, name="points")
        E = evaluation_matrix(self.space.sb, cells, X)
        return np.vstack([E @ self.u[0::2], E @ self.u[1::2]])

    def pressure(self, points, tol: float = 1e-6) -> np.ndarray:
        """Pressure ``(n,)`` at ``points`` ``(2, n)``."""
        cells, X = self.locator.locate(points, tol=tol, name="points")
        return evaluation_matrix(self.space.pb, cells, X) @ self.p

    def vorticity(self) -> np.ndarray:
        """Vorticity ``dv/dx - du/dy`` projected onto the scalar P2 space."""
        return self.space.vorticity(self.u)

    def save(self, path) -> None:
        """Write velocity, pressure, speed and vorticity to a VTU file (quadratic triangles).

        The space's scikit-fem bases are built for it and, unless they were there before,
        released afterwards (:meth:`TaylorHood.release_bases`)."""
        had_bases = self.space.has_bases
        try:
            self._write(path)
        finally:
            if not had_bases:
                self.space.release_bases()

    def _write(self, path) -> None:
        from ..io import write_vtu

        sp_ = self.space
        sb = sp_.sb
        u = np.vstack([self.u[0::2], self.u[1::2]])
        # P1 pressure at P2 nodes (edge midpoints: mean of the end points)
        p = sp_.p1_to_p2 @ self.p
        # skfem sorts the vertices of each element; VTK wants them counter-clockwise
        # (normal +z), with nodes 3, 4, 5 on the edges 01, 12, 20
        cells = sb.element_dofs.T.copy()
        x = sb.doflocs
        e1 = x[:, cells[:, 1]] - x[:, cells[:, 0]]
        e2 = x[:, cells[:, 2]] - x[:, cells[:, 0]]
        cw = e1[0] * e2[1] - e1[1] * e2[0] < 0
        cells[cw] = cells[cw][:, [0, 2, 1, 5, 4, 3]]
        write_vtu(path, sb.doflocs, {"triangle6": cells},
                  point_data={"velocity": u, "pressure": p, "speed": np.hypot(*u),
                              "vorticity": self.vorticity()})
