"""Running a scene: :class:`Simulation` builds what the scene calls for and drives its stepper.

- :mod:`~skfem_granular.simulation.run`: :class:`Simulation`, :class:`SimulationResult`;
- :mod:`~skfem_granular.simulation.effects`: which effects are on, warnings;
- :mod:`~skfem_granular.simulation.dry`: the DEM-only stepper of dry scenes;
- :mod:`~skfem_granular.simulation.checkpoint`: checkpoints and resuming;
- :mod:`~skfem_granular.simulation.budget`: steps, triangles and memory estimated and
  checked against limits before a run;
- :mod:`~skfem_granular.simulation.folder`: an output folder belongs to one run (lock);
- :mod:`~skfem_granular.signals`: SIGINT/SIGTERM stop a run cleanly;
- :mod:`~skfem_granular.simulation.recorder`, :mod:`~skfem_granular.simulation.report`:
  what a run writes as it goes, its summary;
- :mod:`~skfem_granular.simulation.progress`: the progress bar.
"""

from ..coupled.stepper import SimulationError
from .budget import Budget, BudgetError
from .folder import FolderInUseError
from .run import Simulation, SimulationResult

__all__ = ["Budget", "BudgetError", "FolderInUseError", "Simulation", "SimulationError",
           "SimulationResult"]
