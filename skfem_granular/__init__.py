"""skfem-granular: polygonal DEM particles in an incompressible fluid on graded meshes.

The fluid half (Taylor-Hood P2/P1 on scikit-fem) lives in
:mod:`skfem_granular.fluid`, the discrete element method in
:mod:`skfem_granular.dem`; mesh generation is the separate top-level package
:mod:`meshing`.

The names below are imported when first used (:pep:`562`): ``import skfem_granular``
alone, or the command line before it has installed its signal handlers, loads none
of numpy, scipy or scikit-fem.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
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

#: Each public name and the module it comes from.
_WHERE = {
    "Polygon": ".dem", "PrescribedMotion": ".dem",
    "ConvergenceError": ".fluid", "Flow": ".fluid", "Fluid": ".fluid",
    "RigidMotion": ".fluid", "SolveReport": ".fluid", "TaylorHood": ".fluid",
    "UserTerms": ".fluid", "solve_steady": ".fluid",
    "BDF2Integrator": ".fluid.unsteady", "evolve": ".fluid.unsteady",
    "Effects": ".scene", "MeshSpec": ".scene", "ParticleSpec": ".scene", "Scene": ".scene",
    "TimeSpec": ".scene",
    "Simulation": ".simulation", "SimulationError": ".simulation",
    "SimulationResult": ".simulation",
}

__all__ = ["BDF2Integrator", "ConvergenceError", "Effects", "Flow", "Fluid", "MeshSpec",
           "ParticleSpec", "Polygon", "PrescribedMotion", "RigidMotion", "Scene", "Simulation",
           "SimulationError", "SimulationResult", "SolveReport", "TaylorHood", "TimeSpec",
           "UserTerms", "evolve", "solve_steady"]
assert sorted(_WHERE) == __all__


def __getattr__(name: str):
    """The public names, imported at their first use."""
    if name not in _WHERE:
        raise AttributeError(f"module 'skfem_granular' has no attribute {name!r}")
    value = getattr(importlib.import_module(_WHERE[name], __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_WHERE))
