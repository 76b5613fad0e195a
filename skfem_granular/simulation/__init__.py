"""Running a scene: :class:`Simulation` builds what the scene calls for and drives its stepper.

- :mod:`~skfem_granular.simulation.run`: :class:`Simulation`, :class:`SimulationResult`;
- :mod:`~skfem_granular.simulation.effects`: which effects are on, warnings;
- :mod:`~skfem_granular.simulation.dry`: the DEM-only stepper of dry scenes;
- :mod:`~skfem_granular.simulation.checkpoint`: checkpoints and resuming.
"""

from ..coupled.stepper import SimulationError
from .run import Simulation, SimulationResult

__all__ = ["Simulation", "SimulationError", "SimulationResult"]
