"""One coupled BDF2 step tried from a state, without changing anything a failure must keep.

:func:`attempt_step` puts together what a coupling solves (:class:`StepProblem`): the
held forces (weight, callbacks, and through contacts the DEM's substeps), the step's
formula, the first iterate, the moving mesh's callback and any prescribed motions; it
solves, and returns the state the step would reach as an :class:`Attempt`. The DEM is
left as it was: the stepper applies :attr:`Attempt.dem_after` and the new poses when it
accepts the step. :func:`local_error` is the error estimate of adaptive steps.

Steps with a contact force, and the :data:`EULER_AFTER_CONTACT` steps after the last
one, are backward-Euler steps (a contact is an impulse far shorter than the step, and
BDF2 answers it with an overshoot: the design notes).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .. import timestep as ts
from ..dem.motion import pose_derivative
from ..dem.snapshot import DEMSnapshot
from ..fluid.errors import ConvergenceError
from .forcing import ContactPrediction, Forcing
from .problem import StepProblem, StepSolution
from .state import CoupledState

if TYPE_CHECKING:
    from ..dem.system import DEMSystem
    from .mesh_keeper import MeshKeeper

#: Backward-Euler steps after the last step with a contact force.
EULER_AFTER_CONTACT = 2

#: Velocities below this (m/s) count as this in the relative local error.
VELOCITY_FLOOR = 1e-6

#: Steps on a new mesh without an error estimate: the transfer onto a new mesh is not
#: exactly divergence-free and the outlines have moved, so the first step there projects
#: the fluid, and through the added mass the particles, by an amount that does not shrink
#: with the step; the BDF2 derivatives carry that jump for three more steps.
STEPS_BEFORE_ESTIMATE = 4


@dataclass(frozen=True)
class StepParts:
    """What a coupled step is made of besides the state it starts from.

    Attributes
    ----------
    dem : DEMSystem
        The particles at the start of the step (read, not changed).
    forcing : Forcing
        Weight, callbacks and the DEM's contact substeps.
    keeper : MeshKeeper
        The mesh and the coupling on it.
    contacts_active : bool
        Whether contact forces enter the step.
    adaptive : bool
        Whether the step keeps the fluid's BDF2 derivative (error control).
    """

    dem: DEMSystem
    forcing: Forcing
    keeper: MeshKeeper
    contacts_active: bool
    adaptive: bool


@dataclass(frozen=True)
class Attempt:
    """A step solved but not taken.

    Attributes
    ----------
    state : CoupledState
        The histories at the end of the step.
    solution : StepSolution
        The coupling's solution (fluid vector, rigid velocities, forces).
    acceleration : ndarray
        ``(3, K)``: the BDF2 derivative of the rigid velocities.
    poses : ndarray
        ``(3, K)``: the particles' poses at the end of the step.
    dem_after : DEMSnapshot or None
        The DEM after its contact substeps (None: the DEM did not subcycle).
    """

    state: CoupledState
    solution: StepSolution
    acceleration: np.ndarray
    poses: np.ndarray
    dem_after: DEMSnapshot | None


def attempt_step(parts: StepParts, s: CoupledState, step: float) -> Attempt:
    """One coupled step of size ``step`` from ``s``, the DEM holding the particles at ``s.t``.

    Raises
    ------
    ConvergenceError
        When the corrector fails or the solution is not finite (the step is halved).
    """
    dem = parts.dem
    q_n, xi_n = dem.particles.q.copy(), dem.particles.v.copy()
    F_cb, T_cb = parts.forcing.callbacks(s.t + step)
    F_ext, T_ext = parts.forcing.weight() + F_cb, T_cb
    contact = None
    if parts.contacts_active and parts.forcing.contact_possible(step):
        contact = parts.forcing.predict_contacts(step, (s.F_held, s.T_held), (F_cb, T_cb),
                                                 xi_n, F_ext)
        F_ext, T_ext = F_ext + contact.force, T_ext + contact.torque
    touching = contact is not None and contact.touching
    euler = s.dt_prev is None or touching or s.contact_age < EULER_AFTER_CONTACT
    bdf2 = ts.BDF2(step, None if euler else s.dt_prev)
    problem = _problem(parts, s, bdf2, (q_n, xi_n), (F_ext, T_ext), contact)
    sol = parts.keeper.coupling.step(problem)
    q_new = contact.poses if contact is not None else bdf2.solve(sol.xi, q_n, s.q_prev)
    if dem.imposed.any():  # exactly on the trajectory
        q_new = q_new.copy()
        q_new[:, dem.imposed] = dem.prescribed_poses(s.t + step)[:, dem.imposed]
    if not (np.all(np.isfinite(sol.x)) and np.all(np.isfinite(q_new))):
        raise ConvergenceError(f"step at t={s.t + step:.6g}: the solution contains NaN/inf")
    acc = bdf2.derivative(sol.xi, xi_n, problem.xi_prev)
    new = _next_state(parts, s, bdf2, sol, (q_n, xi_n, acc), touching)
    return Attempt(new, sol, acc, q_new, None if contact is None else contact.after)


def _problem(parts: StepParts, s: CoupledState, bdf2: ts.BDF2, start, loads,
             contact: ContactPrediction | None) -> StepProblem:
    """The coupling's problem: histories (none before ``t_n`` for backward Euler), loads,
    the linear extrapolation of the last two states as first iterate, the moving mesh,
    prescribed velocities."""
    q_n, xi_n = start
    # linear extrapolation of the last two states as the Newton initial guess (through
    # contacts the DEM's end-of-substep velocities were tried instead: a 10-50x smaller
    # first update, the same number of iterations)
    w = 0.0 if s.dt_prev is None else bdf2.dt / s.dt_prev
    u_guess = s.u_n if s.u_prev is None else s.u_n + w * (s.u_n - s.u_prev)
    xi_guess = xi_n if s.xi_prev is None else xi_n + w * (xi_n - s.xi_prev)
    keeper, dem = parts.keeper, parts.dem
    geometry = None
    if keeper.ale:
        geometry = keeper.step_geometry(s, bdf2, q_n, None if contact is None else contact.poses)
    xi_imposed = None
    if dem.imposed.any():
        # prescribed motions: the poses at t_{n+1} are the motions'; the velocities their
        # BDF2 derivative (so the pose the BDF2 formula gives back, e.g. the mesh's, is it)
        xi_imposed = pose_derivative(dem.prescribed_poses(s.t + bdf2.dt), q_n, s.q_prev,
                                     bdf2.dt, bdf2.dt_prev)
    F_ext, T_ext = loads
    return StepProblem(bdf2=bdf2, t_new=s.t + bdf2.dt, u_n=s.u_n, xi_n=xi_n, F_ext=F_ext,
                       T_ext=T_ext, u_prev=None if bdf2.euler else s.u_prev,
                       xi_prev=None if bdf2.euler else s.xi_prev, u_guess=u_guess,
                       p_guess=s.p_n, xi_guess=xi_guess,
                       p_prev=s.p_prev, dt_prev=s.dt_prev, geometry=geometry,
                       xi_imposed=xi_imposed)


def _next_state(parts: StepParts, s: CoupledState, bdf2: ts.BDF2, sol: StepSolution, rigid,
                touching: bool) -> CoupledState:
    """The histories at the end of the step (``rigid``: poses, velocities at ``t_n`` and
    the new rigid accelerations)."""
    q_n, xi_n, acc = rigid
    keeper = parts.keeper
    nu = keeper.space.nu
    u_new = sol.x[:nu].copy()
    du = None
    if parts.adaptive:
        du = bdf2.derivative(u_new, s.u_n, None if bdf2.euler else s.u_prev)
    return CoupledState(
        u_n=u_new, p_n=sol.x[nu:].copy(), t=s.t + bdf2.dt, u_prev=s.u_n,
        xi_prev=xi_n, q_prev=q_n, dt_prev=bdf2.dt, F_held=sol.force, T_held=sol.torque,
        du_n=du, du_prev=s.du_n, dxi_n=acc, dxi_prev=s.dxi_n, since_remesh=s.since_remesh + 1,
        contact_age=0 if touching else s.contact_age + 1, euler=bdf2.euler,
        nodes_n=keeper.mesh.p if keeper.ale else None,
        nodes_prev=s.nodes_n if keeper.ale else None,
        p_prev=s.p_n if keeper.coupling.uses_pressure_history else None)


def local_error(s: CoupledState, attempt: Attempt, step: float, radius) -> float | None:
    """Milne estimate of the local error of an attempted step from ``s``, relative; None
    when unknown (no derivative at the start, or fewer than :data:`STEPS_BEFORE_ESTIMATE`
    steps on the mesh).

    A BDF2 step is compared with the AB2 predictor, a backward-Euler step (contacts) with
    the forward-Euler one (Milne factor 1/2). The error is relative to the largest velocity
    (fluid, particle, or ``omega`` times the particle's ``radius``), at least
    :data:`VELOCITY_FLOOR`.
    """
    new, xi_new = attempt.state, attempt.solution.xi
    if (s.dt_prev is None or s.du_n is None or s.dxi_n is None
            or s.since_remesh < STEPS_BEFORE_ESTIMATE):
        return None
    dt_prev = None if new.euler else s.dt_prev
    c = ts.milne_factor(step, dt_prev)
    u_pred = ts.predict(s.u_n, s.du_n, s.du_prev, step, dt_prev)
    assert new.xi_prev is not None  # every step sets it
    xi_pred = ts.predict(new.xi_prev, s.dxi_n, s.dxi_prev, step, dt_prev)
    lever = np.vstack([np.ones((2, radius.size)), radius])  # omega as omega r
    e_u = c * np.abs(new.u_n - u_pred).max()
    e_xi = c * np.abs(lever * (xi_new - xi_pred)).max()
    scale = max(float(np.abs(new.u_n).max()), float(np.abs(lever * xi_new).max()),
                VELOCITY_FLOOR)
    return float(max(e_u, e_xi) / scale)
