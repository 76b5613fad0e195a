"""Fluid and particles together: the one subpackage that knows both meshes and particles.

- :mod:`~skfem_granular.coupled.rigid`: rigid particles as boundaries of one fluid mesh
  (what both couplings share: boundary DOFs, lever arms, consistent forces);
- :mod:`~skfem_granular.coupled.monolithic`: fluid + rigid-body velocities in one BDF2/Newton
  system (the default; stable for every density ratio);
- :mod:`~skfem_granular.coupled.split`: pressure correction with the rigid velocities
  implicit in the projection (:mod:`~skfem_granular.coupled.rigid_projection`): no coupled
  factorisation, for many grains; :mod:`~skfem_granular.coupled.reduced`: the rigid-body
  prolongation both solve on;
- :mod:`~skfem_granular.coupled.partitioned`: the paper's staggered scheme, for comparison;
- :mod:`~skfem_granular.coupled.transfer`: how far particles moved since the mesh was
  built, and fields moved onto a new mesh;
- :mod:`~skfem_granular.coupled.build`: a scene's mesh and coupling;
- :mod:`~skfem_granular.coupled.wake`: the default graded mesh refined while a particle's
  Reynolds number says a wake matters; :mod:`~skfem_granular.coupled.flow_size`: element
  sizes from the flow (an option of the remesh);
- :mod:`~skfem_granular.coupled.state`: the BDF2 histories and the per-step report;
- :mod:`~skfem_granular.coupled.problem`: what a coupling solves in one step and its solution;
- :mod:`~skfem_granular.coupled.forcing`: weight, callbacks and the DEM's contact substeps;
- :mod:`~skfem_granular.coupled.mesh_keeper`: the mesh in use, the coupling on it, its
  motion and the remesh rules (:mod:`~skfem_granular.coupled.ale_rules`,
  :mod:`~skfem_granular.coupled.landing`);
- :mod:`~skfem_granular.coupled.attempt`: one step tried, not taken, and its error estimate;
- :mod:`~skfem_granular.coupled.stepper`: :class:`CoupledStepper`, the loop and the step-size
  policy (``for t, step in stepper.evolve()``).
"""

from .monolithic import MonolithicCoupling
from .partitioned import PartitionedCoupling, Staggering
from .problem import StepProblem, StepSolution
from .rigid import CorrectorOptions, RigidBodies, RigidParticles
from .split import SplitCoupling, SplitOptions
from .state import CoupledState, StepReport
from .stepper import CoupledStepper, SimulationError
from .transfer import FieldTransfer, lag

__all__ = ["CorrectorOptions", "CoupledState", "CoupledStepper", "FieldTransfer",
           "MonolithicCoupling", "PartitionedCoupling", "RigidBodies", "RigidParticles",
           "SplitCoupling", "SplitOptions", "Staggering", "SimulationError", "StepProblem",
           "StepReport", "StepSolution", "lag"]
