"""What a coupled BDF2 step carries over to the next one, and what each accepted step reports."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np


@dataclass(frozen=True)
class CoupledState:
    """The histories the next coupled BDF2 step needs, besides the particles' current state.

    The particles' poses and velocities at ``t`` live in the DEM system (their one
    owner); this holds the fluid state at ``t`` and everything from earlier steps.
    A value: a step or a remesh makes a new one (``dataclasses.replace``).

    Attributes
    ----------
    u_n, p_n : ndarray
        Fluid velocity and pressure DOFs at ``t`` (``p_n`` None before the first step).
    u_prev, xi_prev, q_prev : ndarray or None
        Fluid velocity, rigid velocities ``(3, K)`` and poses ``(3, K)`` at ``t_{n-1}``.
    p_prev : ndarray or None
        Pressure at ``t_{n-1}`` (None after a remesh: not carried over).
    dt_prev : float or None
        The step that led to ``t`` (None: the next step is backward Euler).
    F_held, T_held : ndarray
        Fluid force ``(2, K)`` and torque ``(K,)`` of the last step (held during the
        DEM predictor of the next).
    du_n, du_prev, dxi_n, dxi_prev : ndarray or None
        BDF2 time derivatives of ``u`` and of the rigid velocities at ``t`` and
        ``t_{n-1}`` (the error estimate of adaptive runs).
    dt_next : float or None
        The step the error control proposed.
    error : float
        Local error estimate of the step that led here (NaN if none).
    since_remesh, contact_age : int
        Steps since the fluid state was interpolated, and since the last step with a
        contact force.
    euler : bool
        Whether the step that led here was a backward-Euler step.
    nodes_n, nodes_prev : ndarray or None
        Moving mesh (ALE): vertex positions ``(2, nv)`` at ``t`` and ``t_{n-1}``
        (``nodes_prev`` None: the nodes were at rest before ``t``, as after a remesh).
    """

    #: fields added after checkpoints were first written: read at their defaults from one
    #: that lacks them
    LATER_FIELDS: ClassVar[tuple[str, ...]] = ("p_prev",)
    #: fields checkpoints once held and no longer do: ignored in one that has them
    DROPPED_FIELDS: ClassVar[tuple[str, ...]] = ("x",)

    u_n: np.ndarray
    p_n: np.ndarray | None
    t: float = 0.0
    u_prev: np.ndarray | None = None
    xi_prev: np.ndarray | None = None
    q_prev: np.ndarray | None = None
    dt_prev: float | None = None
    F_held: np.ndarray | None = None
    T_held: np.ndarray | None = None
    du_n: np.ndarray | None = None
    du_prev: np.ndarray | None = None
    dxi_n: np.ndarray | None = None
    dxi_prev: np.ndarray | None = None
    dt_next: float | None = None
    error: float = float("nan")
    since_remesh: int = 1_000_000
    contact_age: int = 1_000_000
    euler: bool = True
    nodes_n: np.ndarray | None = None
    nodes_prev: np.ndarray | None = None
    p_prev: np.ndarray | None = None

    @property
    def x(self) -> np.ndarray | None:
        """The full fluid vector ``[u_n, p_n]`` on the current mesh, a new array (None
        before the first step: no pressure yet)."""
        return None if self.p_n is None else np.concatenate([self.u_n, self.p_n])

@dataclass(frozen=True)
class StepReport:
    """One accepted step, as :meth:`CoupledStepper.evolve` yields it.

    Attributes
    ----------
    t, dt : float
        Time reached and the step taken.
    iterations : int
        Corrector iterations of the step.
    force, torque : ndarray
        Fluid force ``(2, K)`` and torque ``(K,)`` on each particle over the step.
    acceleration : ndarray
        ``(3, K)``: the BDF2 derivative of ``(Vx, Vy, omega)``.
    error : float
        Local error estimate (adaptive runs; NaN otherwise).
    fluid_energy : float
        Kinetic energy of the fluid ``rho u.M u / 2`` (J per unit depth; NaN when dry).
    """

    t: float
    dt: float
    iterations: int
    force: np.ndarray
    torque: np.ndarray
    acceleration: np.ndarray
    error: float = float("nan")
    fluid_energy: float = float("nan")
