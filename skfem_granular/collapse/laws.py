"""Published run-out laws of dry two-dimensional granular column collapses.

``(L_inf - L0) / L0`` against the aspect ratio ``a = H0 / L0``. The coefficients are
approximate (read from the papers' fits; they depend on the grains' friction):

- Lajeunesse, Monnier & Chevalier (2005, Phys. Fluids 17, 103302), quasi-2D channel
  experiments: ``1.2 a`` for ``a < 3``, ``1.9 a^(2/3)`` above;
- Staron & Hinch (2005, J. Fluid Mech. 545, 1-27), 2D contact-dynamics simulations:
  ``lambda a`` with ``lambda ~ 1.2-1.4`` (friction-dependent) at small ``a``,
  ``~ a^(2/3)`` above ``a ~ 2-3`` (here continued from the linear law at a = 3);
- Zenit (2005, Phys. Fluids 17, 031703), 2D disks: ``1.43 a^0.65``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["DRY_LAWS", "dry_runout"]


def _lajeunesse(a):
    return np.where(a < 3.0, 1.2 * a, 1.9 * a ** (2.0 / 3.0))


def _staron_hinch(a, lam=1.3):
    return np.where(a < 3.0, lam * a, lam * 3.0 ** (1.0 / 3.0) * a ** (2.0 / 3.0))


def _zenit(a):
    return 1.43 * a**0.65


#: name -> ``f(a)`` giving ``(L_inf - L0) / L0``
DRY_LAWS = {"Lajeunesse et al. 2005": _lajeunesse, "Staron & Hinch 2005": _staron_hinch,
            "Zenit 2005": _zenit}


def dry_runout(a, law: str = "Lajeunesse et al. 2005") -> np.ndarray:
    """``(L_inf - L0) / L0`` of a dry collapse at aspect ratio ``a`` by a published law."""
    if law not in DRY_LAWS:
        raise ValueError(f"law = {law!r}: must be one of {', '.join(DRY_LAWS)}")
    return DRY_LAWS[law](np.asarray(a, dtype=float))
