"""Polygonal discrete element method (after Matuttis & Chen 2014).

Convex polygonal particles with a *shadow* outline (contacts, mass) and a
smaller *core* outline (the fluid boundary), fixed polygonal walls, overlap-
area contact forces with damping and Cundall-Strack friction, and a BDF2
predictor-corrector integrator; particles may instead follow a prescribed
rigid motion (:class:`PrescribedMotion`: constant velocity, a table of poses
or a function of time). Knows nothing of meshes or fluids: the coupling reads
outlines and velocities and writes ``external_force``.
"""

from .contact_law import ContactForces, ContactHistory, ContactLaw
from .integrator import BDF2History, bdf2_coefficients, stable_time_step
from .motion import PrescribedMotion, pose_derivative
from .output import History, VTUSeries, write_outlines_vtu
from .particles import Body, Particle
from .polygon import Polygon
from .system import DEMSystem
from .walls import box_walls, incline_wall

__all__ = [
    "BDF2History",
    "Body",
    "ContactForces",
    "ContactHistory",
    "ContactLaw",
    "DEMSystem",
    "History",
    "Particle",
    "Polygon",
    "PrescribedMotion",
    "VTUSeries",
    "bdf2_coefficients",
    "box_walls",
    "incline_wall",
    "pose_derivative",
    "stable_time_step",
    "write_outlines_vtu",
]
