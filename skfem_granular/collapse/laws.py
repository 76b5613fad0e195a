"""Published run-out laws of dry two-dimensional granular column collapses.

``(L_inf - L0) / L0`` against the aspect ratio ``a = H0 / L0``, where ``L0`` is the
column's length along the flow in a *one-sided* release (the column stands against a
back wall and flows one way when the gate opens: this project's set-up, and that of
the channel experiments). A symmetric release (a column flowing both ways) is the
same problem with ``L0`` its half-width. ``L_inf`` is the final front: the end of the
deposit's continuous mass, not the farthest isolated grain.

- Lajeunesse, Monnier & Homsy (2005, Phys. Fluids 17, 103302), quasi-2D experiments
  (glass beads in a rectangular channel; ``a = Hi / Li``, ``Li`` the column's length
  along the flow): ``1.2 a`` for ``a <~ 2.3``, ``1.9 a^(2/3)`` above. Coefficients and
  crossover as transcribed by Kumar (2015, PhD thesis, Cambridge, sec. 2.3.1; other
  summaries quote a crossover near 3, which changes nothing below a = 2.3); the
  primary text could not be read here. The two branches do not meet (a jump of 20 %
  at the crossover; they would meet at a = 4).
- Kumar (2015, PhD thesis, Cambridge, ch. 4), 2D DEM of polydisperse disks (0.92-1.38
  mm) with rolling resistance (Iwashita & Oda 1998), contact friction 0.53, wall
  friction 0.47, restitution 0.75, column against a wall behind a gate; front: the
  farthest grain with at least one contact with the main mass: ``1.67 a`` for
  ``a <~ 2.7``, ``2.7 a^(2/3)`` above. Pure 2D runs out further than the
  channel experiments (Kumar: side-wall friction and 3D packing).
- Staron & Hinch (2005, J. Fluid Mech. 545, 1-27), 2D contact-dynamics simulations of
  disks: a power law in ``a`` whose prefactor depends on friction; here ``lambda a``
  with ``lambda = 1.3`` (the middle of the 1.2-1.4 usually quoted) below ``a = 3`` and
  its ``a^(2/3)`` continuation above. Approximate: the coefficients were not checked
  against the paper here.
- Zenit (2005, Phys. Fluids 17, 031703), 2D DEM of disks simulating the cylindrical
  experiments in an equivalent 2D system: ``1.43 a^0.65``, a single power law with no
  transition. Approximate: the prefactor was not checked against the paper here.

Balmforth & Kerswell (2005, J. Fluid Mech. 538, 399-428) measured in narrow slots
``(l_inf - L)/L ~ a^(0.65 +- 0.05)`` and in wide channels ``~ a^(0.9 +- 0.1)``, ``L``
the column's length along the channel, with a material-dependent prefactor; Larrieu,
Staron & Hinch (2006, J. Fluid Mech. 554, 259-270) find ``a^0.65`` for planar collapses.
The prefactors move by tens of percent with the grains' friction and shape.
"""

from __future__ import annotations

import numpy as np

__all__ = ["DRY_LAWS", "dry_runout"]


def _lajeunesse(a):
    return np.where(a < 2.3, 1.2 * a, 1.9 * a ** (2.0 / 3.0))


def _kumar(a):
    return np.where(a < 2.7, 1.67 * a, 2.7 * a ** (2.0 / 3.0))


def _staron_hinch(a, lam=1.3):
    return np.where(a < 3.0, lam * a, lam * 3.0 ** (1.0 / 3.0) * a ** (2.0 / 3.0))


def _zenit(a):
    return 1.43 * a**0.65


#: name -> ``f(a)`` giving ``(L_inf - L0) / L0``
DRY_LAWS = {"Lajeunesse et al. 2005": _lajeunesse, "Kumar 2015 (2D DEM)": _kumar,
            "Staron & Hinch 2005": _staron_hinch, "Zenit 2005": _zenit}


def dry_runout(a, law: str = "Lajeunesse et al. 2005") -> np.ndarray:
    """``(L_inf - L0) / L0`` of a dry collapse at aspect ratio ``a`` by a published law.

    Parameters
    ----------
    a : float or array
        ``H0 / L0``, ``L0`` the column's length along the flow (one-sided release).
    law : str
        A key of :data:`DRY_LAWS`.

    Raises
    ------
    ValueError
        An unknown law, or an aspect ratio that is not finite and positive.
    """
    if law not in DRY_LAWS:
        raise ValueError(f"law = {law!r}: must be one of {', '.join(DRY_LAWS)}")
    a = np.asarray(a, dtype=float)
    if not np.all(np.isfinite(a) & (a > 0)):
        raise ValueError(f"a = {a!r}: the aspect ratio H0 / L0 must be finite and > 0")
    return DRY_LAWS[law](a)
