"""Taylor-Hood P2/P1 Navier-Stokes solvers on scikit-fem."""

from .boundary import RigidMotion
from .errors import ConvergenceError
from .flow import Flow, SolveReport
from .properties import Fluid
from .space import TaylorHood
from .steady import solve_steady
from .unsteady import evolve
from .user_terms import UserTerms

__all__ = ["ConvergenceError", "Flow", "Fluid", "RigidMotion", "SolveReport", "TaylorHood",
           "UserTerms", "evolve",
           "solve_steady"]
