"""Graded and uniform triangle meshes around convex particles (paper Section 5).

Independent of any fluid code: takes plain ``(2, N)`` counter-clockwise
outlines and returns ``skfem.MeshTri`` objects with named boundaries.
"""

from .graded import graded_mesh
from .plot import plot_mesh
from .quality import MeshStats, mesh_stats, remesh_needed
from .uniform import uniform_mesh

__all__ = ["MeshStats", "graded_mesh", "mesh_stats", "plot_mesh", "remesh_needed",
           "uniform_mesh"]
