"""skfem-granular: polygonal DEM particles in an incompressible fluid on graded meshes.

The fluid half (Taylor-Hood P2/P1 on scikit-fem) lives in
:mod:`skfem_granular.fluid`, the discrete element method in
:mod:`skfem_granular.dem`; mesh generation is the separate top-level package
:mod:`meshing`.
"""

from .dem import Polygon, PrescribedMotion
from .fluid import (
    ConvergenceError,
    Flow,
    Fluid,
    RigidMotion,
    SolveReport,
    TaylorHood,
    UserTerms,
    solve_steady,
)
from .fluid.unsteady import BDF2Integrator, evolve
from .scene import Effects, MeshSpec, ParticleSpec, Scene, TimeSpec
from .simulation import Simulation, SimulationError, SimulationResult

__version__ = "0.1.0"

__all__ = ["BDF2Integrator", "ConvergenceError", "Effects", "Flow", "Fluid", "MeshSpec",
           "ParticleSpec", "Polygon", "PrescribedMotion", "RigidMotion", "Scene", "Simulation",
           "SimulationError",
           "SimulationResult",
           "SolveReport", "TaylorHood", "TimeSpec", "UserTerms", "evolve", "solve_steady"]
