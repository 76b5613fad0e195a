"""Material properties of the Newtonian fluid."""

from __future__ import annotations

from dataclasses import dataclass

from .._validate import positive

#: Largest fluid density (kg/m^3): beyond it the mass matrix swamps the viscous and
#: pressure blocks and the saddle-point factorisation fails (1e300 was "exactly singular").
MAX_DENSITY = 1e5
#: Viscosities (Pa s) accepted: from below a gas's to above bitumen's.
VISCOSITY_RANGE = (1e-9, 1e9)


@dataclass(frozen=True)
class Fluid:
    """An incompressible Newtonian fluid.

    Parameters
    ----------
    density : float
        Mass density ``rho_f`` in kg/m^3 (per unit depth in 2D), in
        ``(0, 1e5]`` (:data:`MAX_DENSITY`, beyond every liquid's).
    viscosity : float
        Dynamic viscosity ``eta`` in Pa s, in ``[1e-9, 1e9]``
        (:data:`VISCOSITY_RANGE`: the linear systems stay solvable in float64).

    Examples
    --------
    >>> water = Fluid(density=1000.0, viscosity=1e-3)
    >>> water.kinematic_viscosity
    1e-06
    """

    density: float = 1000.0
    viscosity: float = 1e-3

    def __post_init__(self):
        rho = positive("Fluid.density", self.density)
        if rho > MAX_DENSITY:
            raise ValueError(f"Fluid.density = {self.density!r}: must be a finite number > 0 "
                             f"and <= {MAX_DENSITY:g} kg/m^3")
        object.__setattr__(self, "density", rho)
        lo, hi = VISCOSITY_RANGE
        eta = positive("Fluid.viscosity", self.viscosity)
        if not lo <= eta <= hi:
            raise ValueError(f"Fluid.viscosity = {self.viscosity!r}: must be in [{lo:g}, "
                             f"{hi:g}] Pa s")
        object.__setattr__(self, "viscosity", eta)

    @property
    def kinematic_viscosity(self) -> float:
        """``nu = eta / rho_f`` in m^2/s."""
        return self.viscosity / self.density
