"""The deposition protocols that make a column dense or loose.

Both pour the same grains from the same loose grid (a seeded random order of sizes,
shapes and orientations) into a box of the column's width under gravity, DEM only,
and stop when every grain is at rest. They differ in the contact friction *during
deposition* only:

- ``"dense"``: frictionless grains (``mu = 0``) slide past each other into the
  closest arrangement the polydispersity allows (the usual way to prepare a dense
  random packing, e.g. Kumar, Delenne & Soga; Staron & Hinch);
- ``"loose"``: very rough grains (``mu = 1``) stick where they first touch and keep
  the arches they build, as in a rain of grains.

The collapse afterwards uses its own friction; turning friction on in a packing at
rest keeps it at rest (friction only adds resistance).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["FREEZE", "PROTOCOLS", "Protocol"]


@dataclass(frozen=True)
class Protocol:
    """Contact parameters of a deposition (see the module notes).

    Attributes
    ----------
    mu : float
        Coulomb friction during deposition.
    gamma : float
        Normal (and tangential) damping of the contact law during deposition.
    settle_mu : float
        Friction of the second stage, which brings the grains to rest.
    """

    mu: float
    gamma: float = 0.5
    settle_mu: float = 0.5


#: the named states a packing can be prepared in
PROTOCOLS = {"dense": Protocol(mu=0.0), "loose": Protocol(mu=1.0, settle_mu=1.0)}

#: the first stage ends when the rms speed of the grains is below this many rest speeds
FREEZE = 10.0
