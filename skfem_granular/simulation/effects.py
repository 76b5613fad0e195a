"""Which effects a scene turns on, and what in a scene contradicts itself."""

from __future__ import annotations

import numpy as np

from ..coupled.build import outline_areas


def contacts_needed(scene, dem) -> bool:
    """Whether two shadows, or a shadow and a wall, could meet during the run.

    Compares the smallest gap between bounding circles (particles) and
    between a bounding circle and the domain box (walls) with the distance a
    particle can travel: ``|v0| t + |g| t^2 / 2`` plus a 10 % safety margin
    of the bounding radius (a particle with a prescribed motion: the farthest its
    motion takes a point of it within the run, plus the margin).
    """
    T = scene.time.t_end
    pos = dem.positions
    shadows = dem.shadow_outlines()
    R = np.array([np.linalg.norm(s - pos[:, [k]], axis=0).max() for k, s in enumerate(shadows)])
    speed = np.hypot(*dem.velocities) + np.abs(dem.angular_velocities) * R
    g = np.hypot(*scene.gravity) if scene.effects.gravity else 0.0
    travel = speed * T + 0.5 * g * T**2 + 0.1 * R
    p = dem.particles
    for k in np.flatnonzero(dem.imposed):  # a prescribed motion goes where it says
        travel[k] = p.motions[k].reach(T, p.start[:, k], R[k]) + 0.1 * R[k]
    x0, y0, x1, y1 = scene.domain
    gap_wall = np.min([pos[0] - x0, x1 - pos[0], pos[1] - y0, y1 - pos[1]], axis=0) - R
    if np.any(gap_wall <= travel):
        return True
    if dem.n > 1:
        d = np.linalg.norm(pos[:, :, None] - pos[:, None, :], axis=0)
        gap = d - R[:, None] - R[None, :]
        np.fill_diagonal(gap, np.inf)
        if np.any(gap <= travel[:, None] + travel[None, :]):
            return True
    return False


#: Coupled steps up to this many DEM stable steps resolve a contact: a hexagon hitting the
#: floor at 3 cm/s in water kept 0.76 of the energy of grain + fluid at 1.2 x (5 us, and
#: with adaptive steps), 0.74 at 2.4 x, 0.68 at 4.9 x (backward Euler at contacts).
CONTACT_STEP_FACTOR = 1.25


def scene_warnings(scene, dem, contacts_active: bool) -> list[str]:
    """Contradictions in a scene worth telling the user about."""
    out: list[str] = []
    if scene.dry:
        return out
    fl = scene.fluid
    # Stokes settling speed per unit length is ill-defined in 2D; estimate the particle
    # Reynolds number from the free-fall speed reached in the run, capped by the
    # terminal speed of a sphere of the same diameter (an upper bound in 2D channels).
    rho_p = np.array([p.density for p in scene.particles])
    diam = 2 * np.sqrt(outline_areas(dem.core_outlines()) / np.pi)
    g = np.hypot(*scene.gravity) if scene.effects.gravity else 0.0
    v_fall = np.abs(rho_p - fl.density) / rho_p * g * scene.time.t_end
    v_stokes = np.abs(rho_p - fl.density) * g * diam**2 / (18 * fl.viscosity)
    v0 = np.hypot(*dem.velocities)
    v = np.maximum(np.minimum(v_fall, v_stokes), v0)
    Re = float(np.max(fl.density * v * diam / fl.viscosity))
    if not scene.effects.convection and Re > 1.0:
        out.append(f"convection is off but the particle Reynolds number reaches ~{Re:.2g} > 1: "
                   "unsteady Stokes underestimates the drag; turn effects.convection on")
    if scene.coupling == "partitioned" and np.any(rho_p < 2.0 * fl.density):
        out.append("partitioned coupling with particles lighter than twice the fluid density: "
                   "expect the added-mass instability; use coupling.scheme = 'monolithic'")
    if scene.effects.contacts is False and dem.n > 1:
        out.append("contacts are off with several particles: nothing stops them overlapping")
    limit = CONTACT_STEP_FACTOR * dem.dt_stable
    t = scene.time
    if contacts_active and t.contact_warning and not t.adaptive and t.dt > limit:
        out.append(f"time.dt = {t.dt:g} s does not resolve a contact (steps up to "
                   f"~{limit:.2g} s, {CONTACT_STEP_FACTOR:g} x the DEM's stable step, do): "
                   "the backward-Euler steps at contacts damp bounces more than the contact "
                   "law does (a grain hitting the floor kept 0.68 instead of 0.76 of its energy "
                   "at 4x that step); set time.adaptive = true or a smaller dt if that matters "
                   "(time.contact_warning = false: the step is coarse on purpose)")
    return out
