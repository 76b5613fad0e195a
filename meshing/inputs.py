"""Inputs shared by the builders: their checks and the element-size cap of a domain.

Every builder validates ``domain``, ``particles`` and ``delta_l`` with
:func:`prepare`; the graded kinds also check ``sigma`` and ``relax_rounds``
and stop the element size growing at :func:`size_cap`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .geometry import as_domain, as_particles, centroid, check_layout, positive, subdivide, width

SIGMA_MAX = 1.6
"""Largest accepted growth factor given by the user (element size doubling
within two circles; beyond, the node count per circle drops too abruptly for
the quality bounds). A 10-gon's default from Eq. 4 may reach 1.618."""

WIDTH_FRACTION = 0.5
"""Largest element size over the domain's smallest width (:func:`size_cap`). Without a
cap the circles of a particle in a long narrow channel grow past the channel's width:
a 1 mm disk near the top of a 4 mm x 120 mm channel left the 100 mm below it to a
handful of triangles spanning the channel (smallest angle 2.05 deg). With it the circles
stop growing at half the width (edges there 1.1 times that on average, about two
elements across; 531 vertices, 25.9 deg). Domains where the growth ends below the cap
(the paper's box: 1.49 mm against 1.5 mm) get the same mesh as without it."""


def size_cap(D: NDArray[np.float64]) -> float:
    """Largest element size in domain ``D``: :data:`WIDTH_FRACTION` of its smallest width."""
    return WIDTH_FRACTION * width(D)


def check_rounds(relax_rounds: object) -> None:
    """Raise ValueError unless ``relax_rounds`` is an integer in ``[0, 20]``."""
    if not isinstance(relax_rounds, int | np.integer) or not 0 <= relax_rounds <= 20:
        raise ValueError(f"relax_rounds: must be an integer in [0, 20], got {relax_rounds!r}")


def check_sigma(sigma: float | None) -> float | None:
    """``sigma`` as a float in ``(1, SIGMA_MAX]`` (``None`` kept), or ValueError."""
    if sigma is None:
        return None
    try:
        s = float(sigma)
    except (TypeError, ValueError):
        raise ValueError(f"sigma: expected a number, got {sigma!r}") from None
    if not (np.isfinite(s) and 1.0 < s <= SIGMA_MAX):
        raise ValueError(f"sigma: growth factor must be in (1, {SIGMA_MAX:g}], got {s!r}")
    return s


def prepare(domain: object, particles: object, delta_l: float | None
            ) -> tuple[NDArray, tuple[str, ...], list[NDArray]]:
    """Validate domain, particles and ``delta_l``; return subdivided outlines."""
    D, names = as_domain(domain)
    outlines = as_particles(particles)
    check_layout(D, outlines)
    if outlines:
        radii = [float(np.max(np.hypot(*(P - centroid(P)[:, None])))) for P in outlines]
        k = int(np.argmin(radii))
        delta_l = positive(delta_l, "delta_l", upper=radii[k],
                           what=f" (circumradius of the smallest particle, particles[{k}])")
    else:
        delta_l = positive(delta_l, "delta_l")
    return D, names, [subdivide(P, delta_l) for P in outlines]
