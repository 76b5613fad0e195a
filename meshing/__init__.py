"""Graded and uniform triangle meshes around convex particles (paper Section 5).

Independent of any fluid code: takes plain ``(2, N)`` counter-clockwise
outlines and returns ``skfem.MeshTri`` objects with named boundaries
(``"wall"``, ``"left"``, ``"right"``, ``"bottom"``, ``"top"``,
``"particle0"``, ...).

Builders: :func:`graded_mesh` (concentric circles, Eq. 4),
:func:`uniform_mesh` (equidistant), :func:`group_mesh` (fine region around a
particle group, graded outside), :func:`field_mesh` (size field growing
from the nearest particle at the Eq. 4 rate, gaps resolved: the default for
many particles); each returns a plain ``skfem.MeshTri``.
Mesh with provenance: :func:`build` (``build("graded" | "uniform" | "group" | "field",
domain, particles, **options)``) returns a :class:`BodyFittedMesh`, the same
mesh together with its :class:`Recipe` and the particles' outline vertex
indices, kept beside the mesh so that scikit-fem transforms of the mesh
cannot drop them. Moving particles (on a :class:`BodyFittedMesh`):
:func:`move_particles`, :func:`remesh_needed`, :func:`remesh`. Inspection:
:func:`mesh_stats`, :func:`plot_mesh`.
"""

from .field import field_mesh
from .graded import graded_mesh, ring_radii
from .group import group_mesh
from .plot import plot_mesh
from .quality import MeshStats, mesh_stats, remesh_needed
from .registry import build
from .remesh import move_particles, remesh
from .uniform import uniform_mesh
from .value import BodyFittedMesh, Recipe

__all__ = ["BodyFittedMesh", "MeshStats", "Recipe", "build", "field_mesh", "graded_mesh",
           "group_mesh",
           "mesh_stats", "move_particles", "plot_mesh", "remesh", "remesh_needed",
           "ring_radii", "uniform_mesh"]
