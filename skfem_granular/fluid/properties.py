"""Material properties of the Newtonian fluid."""

from __future__ import annotations

from dataclasses import dataclass

from .._validate import positive


@dataclass(frozen=True)
class Fluid:
    """An incompressible Newtonian fluid.

    Parameters
    ----------
    density : float
        Mass density ``rho_f`` in kg/m^3 (per unit depth in 2D), > 0.
    viscosity : float
        Dynamic viscosity ``eta`` in Pa s, > 0.

    Examples
    --------
    >>> water = Fluid(density=1000.0, viscosity=1e-3)
    >>> water.kinematic_viscosity
    1e-06
    """

    density: float = 1000.0
    viscosity: float = 1e-3

    def __post_init__(self):
        object.__setattr__(self, "density", positive("Fluid.density", self.density))
        object.__setattr__(self, "viscosity", positive("Fluid.viscosity", self.viscosity))

    @property
    def kinematic_viscosity(self) -> float:
        """``nu = eta / rho_f`` in m^2/s."""
        return self.viscosity / self.density
