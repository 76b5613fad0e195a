"""The default mesh's answer to a wake: finer circles once the flow is no longer quiet.

The paper's graded mesh (Eq. 4, ``sigma = 1 + Delta_l / r0``) is fine all round a
particle and coarse a few diameters behind it. That is what a creeping or slow flow
needs, but behind a disk falling at a Reynolds number of a few hundred it damps the
wake: a disk released 10 um off the centreline of a channel stayed within 0.6 um of
it for 0.3 s, where graded circles of sigma = 1.05 let the offset grow to 28 um
(docs/meshing.md).

:class:`WakeGrading` is the indicator and the remedy, applied at every remesh of a
``graded`` mesh built with the default growth factor: while every particle's
Reynolds number ``Re = |v| d / nu`` (``d`` twice the core's circumradius, ``v`` its
velocity, ``nu`` the fluid's kinematic viscosity) stays at or below
:data:`WAKE_REYNOLDS` the remesh keeps the default grading, bit for bit; above it
the remesh grades with :data:`WAKE_SIGMA`, and the
:class:`~skfem_granular.coupled.stepper.CoupledStepper` remeshes at once when a wake
starts on the default circles. The rule reads the particles' velocities only (no
memory): the same state gives the same mesh, and a particle that slows down again
gets the default circles back at its next remesh.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Particle Reynolds number above which the default graded mesh is refined: below the
#: onset of shedding behind a cylinder (Re ~ 47), above the bundled quiet scenes (the
#: paper's single particle: 3.9; the low-Re settling disk ``settling_disk_channel``: 13.9;
#: the drafting disks of ``dkt_two_disks``: 34.9, whose graded mesh is converged).
WAKE_REYNOLDS = 40.0

#: Growth factor of the graded circles above :data:`WAKE_REYNOLDS` (the default is
#: ``1 + Delta_l / r0``, 1.098 for a 64-gon).
WAKE_SIGMA = 1.05


def particle_reynolds(velocities: np.ndarray, radius: np.ndarray, nu: float) -> np.ndarray:
    """``|v| 2 r / nu`` per particle: ``velocities`` ``(2, K)`` (or ``(3, K)``: the first
    two rows), ``radius`` ``(K,)`` the cores' circumradii, ``nu`` in m^2/s."""
    v = np.asarray(velocities, dtype=float)
    return np.hypot(v[0], v[1]) * 2.0 * np.asarray(radius, dtype=float) / float(nu)


@dataclass(frozen=True)
class WakeGrading:
    """Finer graded circles while any particle's Reynolds number exceeds ``reynolds``.

    Attributes
    ----------
    reynolds : float
        Threshold of ``|v| d / nu`` (``> 0``).
    sigma : float
        Growth factor of the circles above it (``1 < sigma <= 1.6``).
    """

    reynolds: float = WAKE_REYNOLDS
    sigma: float = WAKE_SIGMA

    def __post_init__(self):
        ok = isinstance(self.reynolds, int | float) and not isinstance(self.reynolds, bool)
        if not (ok and np.isfinite(self.reynolds) and self.reynolds > 0.0):
            raise ValueError(f"WakeGrading.reynolds = {self.reynolds!r}: must be a finite "
                             "number > 0")
        ok = isinstance(self.sigma, int | float) and not isinstance(self.sigma, bool)
        if not (ok and 1.0 < self.sigma <= 1.6):
            raise ValueError(f"WakeGrading.sigma = {self.sigma!r}: must be in (1, 1.6]")

    def active(self, velocities: np.ndarray, radius: np.ndarray, nu: float) -> bool:
        """Whether any particle's Reynolds number is above :attr:`reynolds`."""
        re = particle_reynolds(velocities, radius, nu)
        return bool(re.size and re.max() > self.reynolds)

    def changes(self, velocities: np.ndarray, radius: np.ndarray, nu: float) -> dict:
        """The builder options of the next remesh: ``{"sigma": sigma}`` above the
        threshold, ``{"sigma": None}`` (the default grading) at or below it."""
        return {"sigma": self.sigma if self.active(velocities, radius, nu) else None}
