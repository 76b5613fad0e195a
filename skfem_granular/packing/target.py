"""A packing at a chosen solid fraction: bisection on the friction during deposition.

The dense protocol (frictionless deposition) and the loose one (``mu = 1``) bound
what pouring reaches for given grains; in between, the solid fraction falls as the
deposition friction grows, on average: a small column is chaotic (30 near-disks, seed
3: 0.853, 0.820, 0.843, 0.805, 0.846, 0.761, 0.787, 0.775 at mu = 0, 1/8, ..., 1).
:func:`prepare_to_fraction` pours the same grains (same seed) with ``mu = 0`` and
``mu = 1`` first: a target outside the range they span is out of reach (one-line
error); inside it, the friction is bisected until the measured fraction is within
``tol`` of the target or ``max_depositions`` are spent (the closest packing is
returned, with a warning naming its fraction). Each deposition costs as much as one
:func:`~skfem_granular.packing.prepare_column`.
"""

from __future__ import annotations

import warnings

import numpy as np

from .deposit import prepare_column
from .packing import Packing
from .protocol import Protocol

__all__ = ["DENSEST", "prepare_to_fraction"]

#: no packing of disks in the plane is denser (Thue: hexagonal packing of equal disks)
DENSEST = np.pi / (2.0 * np.sqrt(3.0))


def _protocol(mu: float) -> Protocol:
    return Protocol(mu=mu, settle_mu=max(mu, 0.5))


def prepare_to_fraction(n: int, aspect: float, target: float, *, tol: float = 0.005,
                        max_depositions: int = 6, **kwargs) -> Packing:
    """A column of ``n`` grains whose solid fraction is ``target`` (within ``tol``).

    Parameters
    ----------
    n, aspect, **kwargs
        As :func:`~skfem_granular.packing.prepare_column` (grains, seed, stiffness, ...).
    target : float
        The wanted solid fraction, in ``(0.5, 0.9069)``.
    tol : float
        Accepted distance of the measured fraction from ``target``.
    max_depositions : int
        At most this many depositions (>= 2: the bounds).

    Raises
    ------
    ValueError
        For a target outside ``(0.5, 0.9069)`` (before any deposition) or outside the
        range the dense and loose protocols reach for these grains (after them).
    """
    if not (isinstance(target, (int, float)) and 0.5 < target < DENSEST):
        raise ValueError(f"packing.target_fraction = {target!r}: must be a number in "
                         f"(0.5, {DENSEST:.4f}) (the densest packing of disks)")
    if not (isinstance(max_depositions, int) and max_depositions >= 2):
        raise ValueError(f"packing.max_depositions = {max_depositions!r}: must be an "
                         "integer >= 2")
    lo_mu, hi_mu = 0.0, 1.0
    dense = prepare_column(n, aspect, _protocol(lo_mu), **kwargs)
    loose = prepare_column(n, aspect, _protocol(hi_mu), **kwargs)
    phi_d, phi_l = dense.solid_fraction, loose.solid_fraction
    if not (phi_l - tol <= target <= phi_d + tol):
        raise ValueError(f"packing.target_fraction = {target:g}: out of reach for these "
                         f"grains, pouring reaches [{phi_l:.4f}, {phi_d:.4f}] (mu = 1 to 0)")
    tried = [dense, loose]
    for _ in range(max_depositions - 2):
        best = min(tried, key=lambda p: abs(p.solid_fraction - target))
        if abs(best.solid_fraction - target) <= tol:
            return best
        mu = 0.5 * (lo_mu + hi_mu)
        p = prepare_column(n, aspect, _protocol(mu), **kwargs)
        tried.append(p)
        if p.solid_fraction > target:
            lo_mu = mu
        else:
            hi_mu = mu
    best = min(tried, key=lambda p: abs(p.solid_fraction - target))
    if abs(best.solid_fraction - target) > tol:
        warnings.warn(f"packing.target_fraction = {target:g}: not reached within tol = {tol:g} "
                      f"in {len(tried)} depositions; the closest, {best.solid_fraction:.4f} "
                      f"({best.state}), is returned (raise max_depositions, or tol)",
                      stacklevel=2)
    return best
