"""What a coupling solves in one step, and what it returns."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..timestep import BDF2


@dataclass(frozen=True)
class StepProblem:
    """One coupled BDF2 (or backward-Euler) step, as a coupling's ``step`` takes it.

    Attributes
    ----------
    bdf2 : BDF2
        The step's formula (``bdf2.dt`` the step; backward Euler without ``dt_prev``).
    t_new : float
        Time at the end of the step.
    u_n, xi_n : ndarray
        Fluid velocity DOFs and rigid velocities ``(3, K)`` at ``t_n``.
    F_ext, T_ext : ndarray
        External forces ``(2, K)`` and torques ``(K,)`` held over the step
        (buoyancy-reduced gravity, contacts, callbacks).
    u_prev, xi_prev : ndarray or None
        The same at ``t_{n-1}`` (not read for backward Euler).
    u_guess, p_guess, xi_guess : ndarray or None
        First iterate of the corrector (default: the state at ``t_n``, zero pressure).
    p_prev : ndarray or None
        The pressure at ``t_{n-1}`` on the current mesh (None: unknown, as after a
        remesh); the split coupling extrapolates the pressure with it.
    dt_prev : float or None
        ``t_n - t_{n-1}`` when ``p_prev`` is given (backward-Euler steps too).
    geometry : callable or None
        Moving mesh (ALE): ``geometry(xi) -> (space, centers, w_mesh)`` for the mesh where
        rigid velocities ``xi`` put the particles at ``t_new``, or None when the mesh in use
        is still that one (:func:`~skfem_granular.coupled.ale_rules.step_geometry`).
    xi_imposed : ndarray or None
        ``(3, K)``: the rigid velocities at ``t_new`` of particles with a prescribed motion
        (their columns are read), Dirichlet data on their outlines.
    """

    bdf2: BDF2
    t_new: float
    u_n: np.ndarray
    xi_n: np.ndarray
    F_ext: np.ndarray
    T_ext: np.ndarray
    u_prev: np.ndarray | None = None
    xi_prev: np.ndarray | None = None
    u_guess: np.ndarray | None = None
    p_guess: np.ndarray | None = None
    xi_guess: np.ndarray | None = None
    p_prev: np.ndarray | None = None
    dt_prev: float | None = None
    geometry: Callable | None = None
    xi_imposed: np.ndarray | None = None

    @property
    def dt(self) -> float:
        """The step."""
        return self.bdf2.dt

    def velocity_scale(self) -> float:
        """The largest fluid or particle speed at ``t_n`` (at least 1e-12): the scale of
        the corrector's stopping tests."""
        return max(float(np.abs(self.u_n).max()), float(np.abs(self.xi_n[:2]).max()), 1e-12)


@dataclass(frozen=True)
class StepSolution:
    """A coupling's solution of one :class:`StepProblem`.

    Attributes
    ----------
    x : ndarray
        The full fluid vector (velocity and pressure DOFs) at ``t_new``.
    xi : ndarray
        ``(3, K)``: rigid velocities ``(Vx, Vy, omega)`` at ``t_new``.
    force, torque : ndarray
        Fluid force ``(2, K)`` and torque ``(K,)`` on each particle.
    iterations : int
        Corrector iterations.
    """

    x: np.ndarray
    xi: np.ndarray
    force: np.ndarray
    torque: np.ndarray
    iterations: int
