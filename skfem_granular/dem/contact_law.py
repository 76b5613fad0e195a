"""Contact law (Matuttis & Chen 2014), vectorised over contact pairs.

Normal force ``F_n = E A / L`` with ``L = 4 r0 r1 / (r0 + r1)``; damping
``gamma sqrt(m_eff E) (dA/dt) / L`` limited to ``[-F_el, cap F_el]`` so the
normal force never attracts and damping never exceeds ``cap`` times the
elastic force; Cundall-Strack tangential spring ``k_t = kt_ratio E l / L``
(``l`` the chord length, so ``k_t / k_n = kt_ratio`` with the normal
stiffness ``k_n = dF_n/d(delta) = E l / L``) with Coulomb limit ``mu F_n``.

Rolling resistance (off unless ``mu_r > 0``): the elastic-plastic spring-dashpot
torque of Iwashita & Oda (1998) in the form Ai et al. (2011) recommend, see
:func:`rolling_torque`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

__all__ = ["ContactHistory", "ContactLaw", "ContactForces", "ROLLING_STIFFNESS",
           "contact_forces", "contact_length", "rolling_torque"]

#: Rolling stiffness ``k_r = ROLLING_STIFFNESS k_n mu_r^2 R_r^2`` (Ai et al. 2011).
ROLLING_STIFFNESS = 2.25


@dataclass(frozen=True)
class ContactLaw:
    """Material parameters of the contact law.

    Parameters
    ----------
    E
        Young's modulus (2D, force per unit length per unit length), ``> 0``.
    mu
        Coulomb friction coefficient, ``>= 0``.
    gamma
        Dimensionless normal damping, ``>= 0`` (0: elastic contacts).
    gamma_t
        Tangential damping (same form with ``k_t``); ``None`` means ``gamma``.
    kt_ratio
        Tangential/normal stiffness ratio (``2/7`` after Cundall-Strack).
    damping_cap
        Damping force at most ``damping_cap`` times the elastic force.
    mu_r
        Rolling friction coefficient, ``>= 0`` (0: no rolling resistance): the
        rolling torque is at most ``mu_r R_r F_n``, ``R_r`` the contact's rolling
        radius (:func:`rolling_torque`).
    eta_r
        Rolling damping ratio, ``>= 0``: the fraction of the rolling spring's
        critical damping (0.3 in Ai et al. 2011).
    """

    #: fields added after checkpoints were first written: read at their defaults from one
    #: that lacks them
    LATER_FIELDS: ClassVar[tuple[str, ...]] = ("mu_r", "eta_r")

    E: float = 1e7
    mu: float = 0.3
    gamma: float = 0.1
    gamma_t: float | None = None
    kt_ratio: float = 2.0 / 7.0
    damping_cap: float = 2.0
    mu_r: float = 0.0
    eta_r: float = 0.3

    def __post_init__(self):
        checks = [("E", self.E, 0.0, False), ("mu", self.mu, 0.0, True),
                  ("gamma", self.gamma, 0.0, True), ("kt_ratio", self.kt_ratio, 0.0, True),
                  ("damping_cap", self.damping_cap, 0.0, True),
                  ("mu_r", self.mu_r, 0.0, True), ("eta_r", self.eta_r, 0.0, True)]
        if self.gamma_t is not None:
            checks.append(("gamma_t", self.gamma_t, 0.0, True))
        for name, v, lo, closed in checks:
            rng = f">= {lo:g}" if closed else f"> {lo:g}"
            if isinstance(v, bool) or not isinstance(v, (int, float, np.number)):
                raise ValueError(f"ContactLaw.{name} = {v!r}: must be a number {rng}")
            x = float(v)
            ok = np.isfinite(x) and (x >= lo if closed else x > lo)
            if not ok:
                raise ValueError(f"ContactLaw.{name} = {v!r}: must be finite and {rng}")
            object.__setattr__(self, name, x)

    @property
    def gt(self) -> float:
        """Effective tangential damping coefficient."""
        return self.gamma if self.gamma_t is None else self.gamma_t

    @property
    def rolls(self) -> bool:
        """Whether contacts resist rolling (``mu_r > 0``)."""
        return self.mu_r > 0.0


class ContactHistory:
    """Tangential spring forces and rolling spring torques per contact pair, kept
    across steps.

    Pairs are identified by the key ``i * nbodies + j``. Pairs missing from a
    new contact list are dropped (the springs reset when contacts separate).
    ``mr`` stays empty while no contact resists rolling.
    """

    def __init__(self):
        self.keys = np.zeros(0, dtype=np.int64)
        self.ft = np.zeros(0)
        self.mr = np.zeros(0)

    def lookup(self, keys: np.ndarray, values: np.ndarray | None = None) -> np.ndarray:
        """Stored tangential forces (or ``values``, e.g. :attr:`mr`) for ``keys``
        (0 for new pairs)."""
        values = self.ft if values is None else values
        if self.keys.size == 0 or keys.size == 0 or values.size == 0:
            return np.zeros(keys.shape)
        idx = np.minimum(np.searchsorted(self.keys, keys), self.keys.size - 1)
        return np.where(self.keys[idx] == keys, values[idx], 0.0)

    def replace(self, keys: np.ndarray, ft: np.ndarray, mr: np.ndarray | None = None) -> None:
        """Store the current contacts' ``keys``, forces and rolling torques, dropping
        all others."""
        order = np.argsort(keys, kind="stable")
        self.keys = keys[order].copy()
        self.ft = ft[order].copy()
        self.mr = np.zeros(0) if mr is None else mr[order].copy()

    def copy(self) -> ContactHistory:
        """An independent copy."""
        h = ContactHistory()
        h.keys, h.ft, h.mr = self.keys.copy(), self.ft.copy(), self.mr.copy()
        return h


class ContactForces:
    """Forces of all active contacts (arrays over contacts ``C``).

    Attributes
    ----------
    i, j
        Body indices (``j >= N`` for walls).
    point
        ``(2, C)`` point of action (overlap centroid).
    normal
        ``(2, C)`` unit normal from ``i`` to ``j``.
    fn, ft
        Normal (``>= 0``, repulsive) and tangential force magnitudes; the
        force on ``i`` is ``-fn n + ft t`` with ``t = (-n_y, n_x)``; on ``j``
        the opposite.
    ft_spring
        Tangential spring force to store in the history.
    mr, mr_spring
        Rolling torque on ``i`` (on ``j`` the opposite) and the rolling spring's
        torque to store; ``None`` when the law has no rolling resistance.
    energy
        ``(C,)`` elastic energy estimate ``E A^2 / (2 L l) + ft^2 / (2 k_t)`` (plus
        ``mr_spring^2 / (2 k_r)`` with rolling resistance).
    keys
        ``(C,)`` contact-history keys of the pairs (set by
        :func:`~skfem_granular.dem.pipeline.apply_contact_law`).
    """

    keys: np.ndarray
    mr: np.ndarray | None = None
    mr_spring: np.ndarray | None = None

    def __init__(self, i, j, point, normal, fn, ft, ft_spring, energy, area):
        self.i, self.j = i, j
        self.point, self.normal = point, normal
        self.fn, self.ft, self.ft_spring = fn, ft, ft_spring
        self.energy = energy
        self.area = area

    @property
    def force_on_i(self) -> np.ndarray:
        """``(2, C)`` force on body ``i``."""
        n = self.normal
        return -self.fn * n + self.ft * np.vstack([-n[1], n[0]])


def contact_length(r0, r1, wall):
    """The law's length ``L = 4 r0 r1 / (r0 + r1)`` (``4 r0`` on a wall), ``r0``, ``r1``
    the distances from the two centroids to the point of action."""
    with np.errstate(divide="ignore", invalid="ignore"):
        L = np.where(wall, 4.0 * r0, 4.0 * r0 * r1 / (r0 + r1))
    return np.maximum(L, 1e-12 * np.maximum(r0, 1e-300))


def contact_forces(law, area, point, normal, length, Xi, Xj, Vi, Vj, wi, wj, m_eff,
                   wall, ft_old, dt):
    """Normal and tangential contact forces for every contact.

    Parameters
    ----------
    law
        :class:`ContactLaw`.
    area, length
        ``(C,)`` overlap area and chord length.
    point, normal
        ``(2, C)`` overlap centroid and unit normal from ``i`` to ``j``.
    Xi, Xj, Vi, Vj
        ``(2, C)`` centroids and velocities of the two bodies.
    wi, wj
        ``(C,)`` angular velocities.
    m_eff
        ``(C,)`` effective mass ``m_i m_j / (m_i + m_j)`` (``m_i`` for walls).
    wall
        ``(C,)`` bool, True where ``j`` is a wall: walls count as infinitely
        large bodies, ``r1 -> inf``, ``L = 4 r0``.
    ft_old
        ``(C,)`` tangential spring force from the previous step.
    dt
        Time step (for the tangential spring increment).

    Returns
    -------
    fn, ft, ft_spring, energy
        ``(C,)`` arrays (see :class:`ContactForces`).
    """
    E = law.E
    ri = point - Xi
    rj = point - Xj
    r0 = np.hypot(ri[0], ri[1])
    r1 = np.hypot(rj[0], rj[1])
    L = contact_length(r0, r1, wall)
    fel = E * area / L
    # relative velocity of i with respect to j at the point of action
    ux = Vi[0] - wi * ri[1] - (Vj[0] - wj * rj[1])
    uy = Vi[1] + wi * ri[0] - (Vj[1] + wj * rj[0])
    vn = ux * normal[0] + uy * normal[1]  # > 0 approaching
    vt = -ux * normal[1] + uy * normal[0]
    kn = E * length / L
    fd = law.gamma * np.sqrt(m_eff * E) * length * vn / L
    fd = np.clip(fd, -fel, law.damping_cap * fel)
    fn = fel + fd
    kt = law.kt_ratio * kn
    spring = ft_old - kt * vt * dt
    total = spring - law.gt * np.sqrt(m_eff * kt) * vt
    limit = law.mu * fn
    slip = np.abs(total) > limit
    ft = np.where(slip, np.sign(total) * limit, total)
    ft_spring = np.where(slip, ft, spring)
    with np.errstate(divide="ignore", invalid="ignore"):
        energy = np.where(length > 0, E * area**2 / (2.0 * L * length), 0.0)
        energy += np.where(kt > 0, ft_spring**2 / (2.0 * kt), 0.0)
    return fn, ft, ft_spring, energy


def rolling_torque(law, fn, kn, R_r, w_rel, I_r, mr_old, dt):
    """Rolling resistance torques of the elastic-plastic spring-dashpot model.

    A spring ``M_k = M_k,old - k_r w_rel dt`` with ``k_r = 2.25 k_n mu_r^2 R_r^2``
    and a dashpot ``-eta_r 2 sqrt(I_r k_r) w_rel`` in parallel (Ai et al. 2011's model
    C, after Iwashita & Oda 1998), their sum limited to the full mobilisation torque
    ``M_m = mu_r R_r F_n``; at the limit the spring holds ``+-M_m`` and the dashpot
    is off (the tangential law's Coulomb limit in the same form: a dashpot beside a
    fresh spring would otherwise exceed ``M_m`` many times over).
    ``w_rel = omega_i - omega_j``: a grain rolling on a plane meets
    ``-M_m sign(omega)``, two grains turning together none.

    Parameters
    ----------
    law
        :class:`ContactLaw` (``mu_r``, ``eta_r``).
    fn, kn
        ``(C,)`` normal force and normal stiffness of the contacts.
    R_r
        ``(C,)`` rolling radius ``r_i r_j / (r_i + r_j)`` (``r_i`` on a wall), ``r`` the
        distances from the centroids to the point of action.
    w_rel
        ``(C,)`` relative angular velocity ``omega_i - omega_j``.
    I_r
        ``(C,)`` equivalent moment of inertia about the point of action,
        ``1 / (1 / (I_i + m_i r_i^2) + 1 / (I_j + m_j r_j^2))``.
    mr_old
        ``(C,)`` spring torque of the previous step.
    dt
        Time step.

    Returns
    -------
    mr, mr_spring, energy
        ``(C,)`` torque on ``i`` (``-mr`` on ``j``), spring torque to store, and the
        spring's elastic energy ``mr_spring^2 / (2 k_r)``.
    """
    kr = ROLLING_STIFFNESS * kn * law.mu_r**2 * R_r**2
    limit = law.mu_r * R_r * fn
    spring = mr_old - kr * w_rel * dt
    total = spring - law.eta_r * 2.0 * np.sqrt(I_r * kr) * w_rel
    held = np.abs(total) > limit
    mr = np.where(held, np.sign(total) * limit, total)
    mr_spring = np.where(held, mr, spring)
    with np.errstate(divide="ignore", invalid="ignore"):
        energy = np.where(kr > 0, mr_spring**2 / (2.0 * kr), 0.0)
    return mr, mr_spring, energy
