"""A mesh and its provenance as one value: :class:`BodyFittedMesh`, :class:`Recipe`.

scikit-fem meshes are dataclasses whose transforms (``replace``,
``with_boundaries``, ``refined``, ...) return new meshes, so anything set on a
mesh as an extra attribute gets lost. How a mesh was built (:class:`Recipe`)
and where the particle outlines sit in it (``particle_nodes``) therefore live
next to the mesh in a :class:`BodyFittedMesh`, never on it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import skfem
from numpy.typing import NDArray

from .registry import build


@dataclass(frozen=True)
class Recipe:
    """How a mesh was built, so that it can be built again for moved particles.

    Attributes
    ----------
    kind : str
        ``"graded"``, ``"uniform"``, ``"group"`` or ``"field"`` (see :func:`meshing.build`).
    domain : object
        The ``domain`` argument as given to the builder.
    particles : tuple of ndarray
        The particle outlines ``(2, N)`` after ``delta_l`` subdivision, in
        particle order.
    options : dict
        The builder's keyword arguments except ``domain`` and ``particles``
        (defaults filled in; ``h`` as computed when it was left to default).
    """

    kind: str
    domain: Any
    particles: tuple[NDArray[np.float64], ...]
    options: dict[str, Any] = field(default_factory=dict)

    def build(self) -> BodyFittedMesh:
        """Build the mesh this recipe describes.

        Returns
        -------
        BodyFittedMesh
            ``meshing.build(kind, domain, particles, **options)``.
        """
        return build(self.kind, self.domain, self.particles, **self.options)

    def __repr__(self) -> str:
        opts = ", ".join(f"{k}={v!r}" for k, v in self.options.items() if v is not None)
        dom = self.domain if isinstance(self.domain, tuple) else "outline"
        return (f"Recipe({self.kind!r}, domain={dom}, {len(self.particles)} particles"
                + (f", {opts})" if opts else ")"))


@dataclass(frozen=True, eq=False)
class BodyFittedMesh:
    """A triangle mesh around particles together with how it was built.

    Made by :func:`meshing.build`, :func:`meshing.remesh` and
    :func:`meshing.move_particles`. Transform the mesh with scikit-fem as
    usual and keep the provenance with ``dataclasses.replace(value,
    mesh=new_mesh)`` (valid as long as the vertex numbering is kept).
    Comparison is by identity; compare the arrays to compare meshes.

    Attributes
    ----------
    mesh : skfem.MeshTri
        The mesh, with named ``boundaries`` ``"wall"`` (and ``"bottom"``,
        ``"right"``, ``"top"``, ``"left"`` for a rectangle) and
        ``"particle0"``, ``"particle1"``, ...; ``subdomains`` ``"fine"`` and
        ``"graded"`` for a group mesh.
    recipe : Recipe or None
        How the mesh was built; ``None`` if unknown (such a value cannot be
        remeshed or moved).
    particle_nodes : tuple of ndarray
        One integer array per particle: the vertex indices of its outline in
        ``mesh``, in outline order, so ``mesh.p[:, particle_nodes[k]]`` is the
        (subdivided) outline of particle ``k``. A ``"field"`` mesh may add nodes
        on outline edges along a narrow gap: they lie on the boundary
        ``"particle{k}"`` (its facets' nodes are all of the particle's nodes),
        not in ``particle_nodes``.
    """

    mesh: skfem.MeshTri
    recipe: Recipe | None
    particle_nodes: tuple[NDArray[np.int64], ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "particle_nodes",
                           tuple(np.asarray(idx) for idx in self.particle_nodes))

    def __repr__(self) -> str:
        kind = "no recipe" if self.recipe is None else repr(self.recipe.kind)
        return (f"BodyFittedMesh({kind}: {self.mesh.p.shape[1]} vertices, "
                f"{self.mesh.t.shape[1]} triangles, {len(self.particle_nodes)} particles)")


def mesh_of(mesh: object) -> Any:
    """The ``skfem`` mesh of a :class:`BodyFittedMesh`, or ``mesh`` itself."""
    return mesh.mesh if isinstance(mesh, BodyFittedMesh) else mesh
