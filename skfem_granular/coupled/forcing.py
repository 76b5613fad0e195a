"""The forces a coupled step holds fixed: weight, user callbacks, and the DEM's contacts.

With contacts the DEM subcycles over the step with the last fluid force held and gives
the positions at the end of the step and the mean contact force (from the momentum
change, so the impulse of a short contact counts in full). The subcycling is tried on
the DEM and taken back at once: the DEM changes only when the step is accepted
(:attr:`ContactPrediction.after`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..dem.snapshot import DEMSnapshot
from .build import CoreSizes


@dataclass(frozen=True)
class ContactPrediction:
    """The DEM's substeps over one coupled step.

    Attributes
    ----------
    force, torque : ndarray
        Mean contact force ``(2, K)`` and torque ``(K,)`` over the step.
    poses : ndarray
        ``(3, K)`` poses at the end of the step.
    touching : bool
        Whether a contact force acted (more than the round-off of the momentum
        difference it comes from), or a contact is open at the end of the step.
    after : DEMSnapshot
        The DEM at the end of its substeps, for when the step is accepted.
    """

    force: np.ndarray
    torque: np.ndarray
    poses: np.ndarray
    touching: bool
    after: DEMSnapshot


class Forcing:
    """External forces on the particles of a coupled scene.

    Parameters
    ----------
    scene : Scene
        Gravity (when ``effects.gravity``) and the fluid density (buoyancy).
    dem : DEMSystem
        The particles: masses, force callbacks, contacts.
    cores : CoreSizes
        Core areas (buoyancy) and radii.
    timings : dict
        ``"dem"``: wall time of the DEM's substeps is added.
    """

    def __init__(self, scene, dem, cores: CoreSizes, timings: dict):
        self.dem, self.cores, self.timings = dem, cores, timings
        self.g = np.asarray(scene.gravity) if scene.effects.gravity else np.zeros(2)
        self.fluid_density = scene.fluid.density

    def weight(self) -> np.ndarray:
        """Buoyancy-reduced gravity ``(m - rho_f A_core) g`` of the particles, ``(2, K)``.

        Buoyancy is that of the core, the outline the fluid sees (the hydrostatic
        pressure is left out of the solved pressure)."""
        return (np.outer(self.g, self.dem.mass)
                - self.fluid_density * np.outer(self.g, self.cores.area))

    def callbacks(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """The DEM's ``force_callbacks`` ``f(dem, t) -> (F (2, K), T (K,))``, summed.

        A coupled step evaluates them once, at its end time ``t`` with the particles where
        the step starts, and holds them over the step as it holds the other external
        forces (the DEM's substeps through contacts see the same held value)."""
        dem = self.dem
        F, T = np.zeros((2, dem.n)), np.zeros(dem.n)
        for i, f in enumerate(dem.force_callbacks):
            try:
                Fc, Tc = f(dem, t)
                F = F + np.broadcast_to(np.asarray(Fc, dtype=float), (2, dem.n))
                T = T + np.broadcast_to(np.asarray(Tc, dtype=float), (dem.n,))
            except (TypeError, ValueError) as exc:
                raise ValueError(f"force_callbacks[{i}]: must return (F, T) of shapes (2, "
                                 f"{dem.n}) and ({dem.n},) (or broadcastable): {exc}") from None
        return F, T

    def contact_possible(self, dt: float) -> bool:
        """Whether a contact can act within a step ``dt`` (else the DEM's substeps would
        only integrate the rigid-body motion that the coupled step integrates itself)."""
        return self.dem.contact_possible(dt, float(np.hypot(*self.g)))

    def predict_contacts(self, dt: float, fluid_held, callbacks_held, xi_n,
                         F_ext) -> ContactPrediction:
        """Subcycle the DEM over ``dt``, then put it back as it was.

        Parameters
        ----------
        dt : float
            The step.
        fluid_held : tuple of ndarray
            The fluid force ``(2, K)`` and torque ``(K,)`` of the last step.
        callbacks_held : tuple of ndarray
            The callbacks' force and torque (:meth:`callbacks`; the DEM does not
            evaluate its callbacks again in its substeps).
        xi_n : (3, K) ndarray
            Rigid velocities at the start of the step.
        F_ext : (2, K) ndarray
            The other external forces of the step (for the round-off bound).
        """
        t0 = time.perf_counter()
        dem = self.dem
        before = dem.snapshot()
        F_held = fluid_held[0] + callbacks_held[0]
        T_held = fluid_held[1] + callbacks_held[1]
        dem.external_force[...] = F_held - self.fluid_density * np.outer(self.g, self.cores.area)
        dem.external_torque[...] = T_held
        v0 = dem.velocities.copy()
        w0 = dem.angular_velocities.copy()
        callbacks, dem.force_callbacks = dem.force_callbacks, []
        try:
            dem.advance(dt)
        finally:
            dem.force_callbacks = callbacks
        F_c = (dem.mass * (dem.velocities - v0) / dt - np.outer(self.g, dem.mass)
               - dem.external_force)
        T_c = dem.inertia * (dem.angular_velocities - w0) / dt - dem.external_torque
        if dem.imposed.any():  # moved by their motion, not by forces: no contact force
            F_c[:, dem.imposed] = 0.0
            T_c[dem.imposed] = 0.0
        touching = self._acted(xi_n, dt, F_ext, (F_c, T_c), fluid_held[0])
        prediction = ContactPrediction(F_c, T_c, dem.particles.q.copy(), touching,
                                       dem.snapshot())
        dem.restore_snapshot(before)
        self.timings["dem"] += time.perf_counter() - t0
        return prediction

    def _acted(self, xi_n, dt, F_ext, contact, F_fluid) -> bool:
        """Whether the mean contact force is more than the round-off of the momentum
        difference it comes from (or a contact is open at the end of the substeps)."""
        dem = self.dem
        if dem.contact_count().max() > 0:
            return True
        F_c, T_c = contact
        eps = 1e3 * np.finfo(float).eps
        v = np.abs(np.concatenate([xi_n[:2], dem.velocities], axis=1)).max()
        noise = eps * (dem.mass.max() * v / dt + np.abs(F_ext).max() + np.abs(F_fluid).max())
        return bool(np.abs(F_c).max() > noise or np.abs(T_c / self.cores.radius).max() > noise)
