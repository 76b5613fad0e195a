"""Taylor-Hood P2/P1 Navier-Stokes solvers on scikit-fem."""

from .boundary import RigidMotion
from .errors import ConvergenceError
from .flow import Flow, SolveReport
from .properties import Fluid
from .space import TaylorHood
from .steady import solve_steady

__all__ = ["ConvergenceError", "Flow", "Fluid", "RigidMotion", "SolveReport", "TaylorHood",
           "solve_steady"]
