"""The time loop of a coupled run: one step at a time, with retries.

:func:`run_coupled` advances a :class:`~skfem_granular.simulation.Simulation`
with fluid to ``t_end``. A step whose corrector does not converge is retried
with half the step (at most ``MAX_RETRIES`` times, the DEM state restored
first); the following steps grow back towards the scene's ``dt`` by at most
a factor 2 per step (variable-step BDF2 is zero-stable below 1 + sqrt(2)).

With ``time.adaptive`` the steps follow the local error estimate as in the
fluid core's :func:`~skfem_granular.fluid.evolve`: an explicit second-order
(AB2) predictor of the fluid velocities and the particles' rigid velocities,
Milne's device on the predictor-corrector difference, and
:class:`~skfem_granular.timestep.StepController` to accept or reject the
step and propose the next one (at most the scene's ``dt``). The error is
relative to the largest velocity (fluid, particle, or ``omega`` times the
particle's radius), at least :data:`VELOCITY_FLOOR`.

The first four steps on a new mesh keep their size without an estimate.
Interpolation onto a new mesh is not exactly divergence-free and the
particle surfaces have moved, so the first step on a new mesh projects the
fluid, and through the added mass the particles, by an amount that does not
shrink with the step (measured: 20 % of the largest fluid velocity and
0.15 % of the particle's, for a particle at Re 100 remeshed every 6.5 um),
and the BDF2 derivatives carry that jump for three more steps. An estimate
that includes it rejects every step down to ``dt_min``.

Steps with a contact force, and the two after the last one, are
backward-Euler steps. A contact is an impulse far shorter than the step
(DEM subcycles resolve it); BDF2 answers such a kick with an overshoot
(it is A- and G-stable, but its kinetic energy is not monotone), and with
BDF2 throughout a hexagon hitting the floor at 3 cm/s in water came back
with 1.37, 1.16, 0.98 times the kinetic energy of grain + fluid at fixed
steps of 20, 10, 5 us (the energy kept rising for 2-3 steps after the
contact had ended, with no contact force in them), and a grain resting on
the floor rattled at 8e-5 m/s. Backward Euler is monotone: 0.68, 0.74,
0.76 of the energy at 20, 10, 5 us (0.76 adaptive), the resting grain
still to 5e-12 m/s. The fluid is first-order accurate in time during
contacts (``euler_steps_at_contacts`` in the summary counts those steps).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from . import timestep as ts
from .fluid.errors import ConvergenceError

#: Halvings of a step before the run gives up.
MAX_RETRIES = 4

#: Rejections of one step by the error control before the run gives up.
MAX_REJECTIONS = 10

#: Velocities below this (m/s) count as this in the relative local error.
VELOCITY_FLOOR = 1e-6

#: Backward-Euler steps after the last step with a contact force (module notes).
EULER_AFTER_CONTACT = 2

class SimulationError(RuntimeError):
    """A run stopped early; the history and the last good state were written."""


@dataclass
class CoupledState:
    """Fluid and particle histories needed by the next BDF2 step."""

    u_n: np.ndarray
    p_n: np.ndarray | None
    xi_n: np.ndarray
    q_n: np.ndarray
    t: float = 0.0
    u_prev: np.ndarray | None = None
    xi_prev: np.ndarray | None = None
    q_prev: np.ndarray | None = None
    dt_prev: float | None = None
    F_held: np.ndarray | None = None
    T_held: np.ndarray | None = None
    x: np.ndarray | None = None
    du_n: np.ndarray | None = None  # BDF2 time derivative of u at t (adaptive runs)
    du_prev: np.ndarray | None = None
    dxi_n: np.ndarray | None = None  # ... of the rigid velocities (the accelerations)
    dxi_prev: np.ndarray | None = None
    dt_next: float | None = None  # the step the error control proposed
    error: float = float("nan")  # local error estimate of the step that led here
    since_remesh: int = 1_000_000  # steps since the fluid state was interpolated
    contact_age: int = 1_000_000  # steps since the last one with a contact force
    euler: bool = True  # the step that led here was a backward-Euler step


def initial_state(sim) -> CoupledState:
    """Fluid at rest, particles as the DEM holds them."""
    dem = sim.dem
    return CoupledState(u_n=np.zeros(sim.space.nu), p_n=None,
                        xi_n=np.vstack([dem.velocities, dem.angular_velocities[None, :]]).copy(),
                        q_n=np.vstack([dem.positions, dem.angles[None, :]]).copy(),
                        F_held=np.zeros((2, dem.n)), T_held=np.zeros(dem.n),
                        x=np.zeros(sim.space.N))


def coupled_step(sim, s: CoupledState, step: float):
    """One coupled BDF2 step of size ``step``; returns the new state and the solver result.

    With contacts, the DEM goes first, subcycled with the last fluid force held: it
    gives the positions and the mean contact force over the step, which enters the
    coupled solve. Steps with a contact force, and the :data:`EULER_AFTER_CONTACT`
    steps after the last one, are backward-Euler steps (see the module notes).
    """
    F_ext, T_ext = sim._external()
    t0 = time.perf_counter()
    touching = False
    if sim.contacts_active:
        F_c, T_c, q_dem = sim._dem_predictor(step, s.F_held, s.T_held)
        touching = _contact_force_acted(sim, s, step, F_ext, F_c, T_c)
        F_ext, T_ext = F_ext + F_c, T_ext + T_c
    sim.timings["dem"] += time.perf_counter() - t0
    euler = s.dt_prev is None or touching or s.contact_age < EULER_AFTER_CONTACT
    dt_prev = None if euler else s.dt_prev
    u_prev = None if euler else s.u_prev
    xi_prev = None if euler else s.xi_prev
    if euler and s.dt_prev is not None:
        sim.euler_steps += 1
    # linear extrapolation of the last two states as the Newton initial guess
    w = 0.0 if s.dt_prev is None else step / s.dt_prev
    u_guess = s.u_n if s.u_prev is None else s.u_n + w * (s.u_n - s.u_prev)
    xi_guess = s.xi_n if s.xi_prev is None else s.xi_n + w * (s.xi_n - s.xi_prev)
    res = sim.coupling.step(step, dt_prev, s.u_n, u_prev, s.xi_n, xi_prev, F_ext, T_ext,
                            s.t + step, p_guess=s.p_n, u_guess=u_guess, xi_guess=xi_guess)
    a0, a1, a2 = ts.bdf2_coefficients(step, dt_prev)
    xi_new = res["xi"]
    if sim.contacts_active:
        q_new = q_dem
    else:
        q_new = (xi_new - a1 * s.q_n - (a2 * s.q_prev if dt_prev is not None else 0.0)) / a0
    x = res["x"]
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(q_new))):
        raise ConvergenceError(f"step at t={s.t + step:.6g}: the solution contains NaN/inf")
    acc = a0 * xi_new + a1 * s.xi_n + (a2 * xi_prev if xi_prev is not None else 0.0)
    nu = sim.space.nu
    u_new = x[:nu].copy()
    du = None
    if sim.scene.time.adaptive:
        du = a0 * u_new + a1 * s.u_n + (a2 * u_prev if u_prev is not None else 0.0)
    new = CoupledState(u_n=u_new, p_n=x[nu:].copy(), xi_n=xi_new, q_n=q_new,
                       t=s.t + step, u_prev=s.u_n, xi_prev=s.xi_n, q_prev=s.q_n, dt_prev=step,
                       F_held=res["force"], T_held=res["torque"], x=x,
                       du_n=du, du_prev=s.du_n, dxi_n=acc, dxi_prev=s.dxi_n,
                       since_remesh=s.since_remesh + 1,
                       contact_age=0 if touching else s.contact_age + 1, euler=euler)
    return new, res, acc


def _contact_force_acted(sim, s: CoupledState, step: float, F_ext, F_c, T_c) -> bool:
    """Whether the DEM predictor's mean contact force is more than the round-off of the
    momentum difference it comes from (or a contact is open at the end of the step)."""
    dem = sim.dem
    if dem.contact_count().max() > 0:
        return True
    eps = 1e3 * np.finfo(float).eps
    v = np.abs(np.concatenate([s.xi_n[:2], dem.velocities], axis=1)).max()
    noise = eps * (dem.mass.max() * v / step + np.abs(F_ext).max() + np.abs(s.F_held).max())
    return bool(np.abs(F_c).max() > noise or np.abs(T_c / sim.radius).max() > noise)


def local_error(sim, s: CoupledState, new: CoupledState, step: float) -> float | None:
    """Milne estimate of the local error of the step ``s -> new``, relative; None if unknown.

    A BDF2 step is compared with the AB2 predictor, a backward-Euler step (contacts)
    with the forward-Euler one (Milne factor 1/2). Needs the derivative at ``s``.
    """
    if s.dt_prev is None or s.du_n is None or s.dxi_n is None or s.since_remesh < 4:
        return None
    dt_prev = None if new.euler else s.dt_prev
    c = ts.milne_factor(step, dt_prev)
    u_pred = ts.predict(s.u_n, s.du_n, s.du_prev, step, dt_prev)
    xi_pred = ts.predict(s.xi_n, s.dxi_n, s.dxi_prev, step, dt_prev)
    lever = np.vstack([np.ones((2, sim.radius.size)), sim.radius])  # omega counts as omega r
    e_u = c * np.abs(new.u_n - u_pred).max()
    e_xi = c * np.abs(lever * (new.xi_n - xi_pred)).max()
    scale = max(float(np.abs(new.u_n).max()), float(np.abs(lever * new.xi_n).max()),
                VELOCITY_FLOOR)
    return float(max(e_u, e_xi) / scale)



def _commit_particles(sim, s: CoupledState):
    dem = sim.dem
    dem.positions[...] = s.q_n[:2]
    dem.angles[...] = s.q_n[2]
    dem.velocities[...] = s.xi_n[:2]
    dem.angular_velocities[...] = s.xi_n[2]
    dem.t = s.t
    if sim.contacts_active:
        dem.reset_history()  # velocities were set by the coupled solve


def run_coupled(sim, hist, series, bar, start: CoupledState | None = None,
                k0: int = 0) -> CoupledState:
    """Advance to ``t_end`` with retries; returns the last good state.

    Raises
    ------
    SimulationError
        When a step does not converge after :data:`MAX_RETRIES` halvings;
        the caller writes the history and the last good state.
    """
    from . import checkpoint

    sc = sim.scene
    t_end, dt = sc.time.t_end, sc.time.dt
    if start is None:
        s = initial_state(sim)
        sim._write_frame(series, 0.0, x=s.x)
    else:
        s = start
    sim.last_good = s
    eps = 1e-9 * dt
    k = k0
    every = sc.checkpoint_every
    ctrl = None
    if sc.time.adaptive:
        ctrl = ts.StepController(tol=sc.time.tol, dt_min=sc.time.dt_min, dt_max=dt)
    step_target = dt if s.dt_prev is None else min(dt, 2.0 * s.dt_prev)
    if ctrl is not None and s.dt_next is not None:
        step_target = s.dt_next
    while s.t < t_end - eps:
        step = min(step_target, dt)
        if s.dt_prev is not None:
            step = min(step, 2.0 * s.dt_prev)
        remaining = t_end - s.t
        # land on t_end; keep the step (and the factorisation) if only rounding differs
        if remaining < step and abs(remaining - step) > eps:
            step = remaining
        new, res, acc, step = _accepted_step(sim, s, step, ctrl)
        step_target = min(dt, 2.0 * step) if ctrl is None else new.dt_next
        s = new  # t is the sum of the steps, not snapped to t_end (resumed runs stay bitwise)
        _commit_particles(sim, s)
        sim.last_good = s
        k += 1
        sim._record(hist, s.t, step, res["iterations"], acc, res["force"], res["torque"],
                    u=s.u_n, error=s.error)
        if sim._frame_due_time(k, s.t):
            sim._write_frame(series, s.t, x=s.x)
        if s.t < t_end - eps:
            n_meshes = sim.remeshes
            s.u_n, s.u_prev, s.p_n, s.du_n, s.du_prev = sim._maybe_remesh(
                s.u_n, s.u_prev, s.p_n, s.du_n, s.du_prev)
            if sim.remeshes > n_meshes:
                s.since_remesh = 0
        if every and sim.output_dir is not None and k % every == 0:
            checkpoint.save(sim, s, k, hist, series)
        bar.update(1)
    return s


def _accepted_step(sim, s: CoupledState, step: float, ctrl):
    """One step from ``s``: halved on solver failure, and under error control (``ctrl``)
    rejected and retried until the local error is within tolerance.

    Returns ``(new state, solver result, accelerations, the step taken)``.
    """
    saved = sim.dem.save_state() if sim.contacts_active else None
    rejections = 0
    while True:
        for attempt in range(MAX_RETRIES + 1):
            try:
                new, res, acc = coupled_step(sim, s, step)
                break
            except ConvergenceError as exc:
                if saved is not None:
                    sim.dem.restore_state(saved)
                if attempt == MAX_RETRIES:
                    raise SimulationError(
                        f"run stopped at t={s.t:.6g} s: {exc} (after {MAX_RETRIES} step "
                        f"halvings down to dt={step:.3g} s)") from exc
                sim.retries += 1
                step *= 0.5
        if ctrl is None:
            return new, res, acc, step
        err = local_error(sim, s, new, step)
        # the backward-Euler start has no estimate: keep its step
        accepted, proposal = (True, step) if err is None else ctrl.propose(step, err)
        if accepted:
            new.error = float("nan") if err is None else err
            new.dt_next = proposal
            return new, res, acc, step
        if saved is not None:
            sim.dem.restore_state(saved)
        sim.rejections += 1
        rejections += 1
        if rejections > MAX_REJECTIONS or proposal <= ctrl.dt_min:
            raise SimulationError(
                f"run stopped at t={s.t:.6g} s: local error {err:.3g} > time.tol = "
                f"{ctrl.tol:g} after {rejections} rejections down to dt={step:.3g} s "
                f"(time.dt_min = {ctrl.dt_min:g})")
        step = proposal
