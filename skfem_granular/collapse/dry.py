"""A dry collapse run until the deposit is at rest, and its final run-out.

:func:`run_dry` releases a packing in its dry tank (:func:`~.setup.column_scene`,
``fluid=False``) and stops when the grains' kinetic energy has fallen below
``stop_ratio`` of its peak (after ``t_min_tau`` free-fall times ``tau_c``), or at
``t_max_tau``. The final run-out ``(L_inf - L0) / L0`` is read with
:func:`~.measures.mass_front`, the front of the deposit's continuous mass, as the
published laws define it (:mod:`.laws`).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..packing import Packing
from .measures import front_position, mass_front, normalised_runout
from .setup import FRICTION, column_scene, time_scale

__all__ = ["DryCollapse", "run_dry"]


@dataclass
class DryCollapse:
    """The outcome of :func:`run_dry`.

    Attributes
    ----------
    sim : Simulation
        The finished run (grains in ``sim.dem``, rows in ``sim.history``).
    runout : float
        ``(L_inf - L0) / L0`` with the mass front (grains in contact with the mass).
    runout_gap : float
        The same with :func:`~.measures.front_position` (grains within one grain's
        width of the mass count).
    t_over_tau : float
        When the run stopped, in ``tau_c = sqrt(H0 / g)``.
    at_rest : bool
        Whether it stopped on the energy criterion (False: at ``t_max_tau``).
    energy_ratio : float
        Kinetic energy at the stop over its peak.
    """

    sim: object
    runout: float
    runout_gap: float
    t_over_tau: float
    at_rest: bool
    energy_ratio: float


def run_dry(packing: Packing, *, mu: float = FRICTION, mu_r: float = 0.0, stop_ratio: float = 1e-4,
            t_min_tau: float = 3.0, t_max_tau: float = 20.0) -> DryCollapse:
    """Release ``packing`` dry and run until the grains are at rest.

    Parameters
    ----------
    packing : Packing
    mu : float
        Contact friction (grains and walls; default tan 26 deg).
    mu_r : float
        Rolling friction coefficient (0: free rolling).
    stop_ratio : float
        At rest when the kinetic energy is below this fraction of its peak, in (0, 1).
    t_min_tau, t_max_tau : float
        Earliest stop and latest end, in ``tau_c``; ``0 <= t_min_tau < t_max_tau``.
    """
    if not 0.0 < stop_ratio < 1.0:
        raise ValueError(f"stop_ratio = {stop_ratio!r}: must be in (0, 1)")
    if not 0.0 <= t_min_tau < t_max_tau:
        raise ValueError(f"t_min_tau = {t_min_tau!r}, t_max_tau = {t_max_tau!r}: must "
                         "satisfy 0 <= t_min_tau < t_max_tau")
    from ..simulation import Simulation  # the simulation package: imported when used

    tau = time_scale(packing)
    sim = Simulation(column_scene(packing, fluid=False, mu=mu, mu_r=mu_r,
                                  t_end=t_max_tau * tau))
    peak, E, at_rest, t = 0.0, 0.0, False, 0.0
    for t, _ in sim.evolve():
        E = sim.dem.kinetic_energy()
        peak = max(peak, E)
        if t > t_min_tau * tau and E < stop_ratio * peak:
            at_rest = True
            break
    final = sim.dem.shadow_outlines()
    L0 = packing.width
    return DryCollapse(sim=sim, runout=float(normalised_runout(mass_front(final), L0)),
                       runout_gap=float(normalised_runout(front_position(final), L0)),
                       t_over_tau=t / tau, at_rest=at_rest,
                       energy_ratio=E / peak if peak > 0 else 0.0)
