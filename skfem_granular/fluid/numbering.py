"""A field's element and DOF numbering on a mesh, without a scikit-fem basis.

Building a basis computes its values at every quadrature point (about 20 ms at 20k
nodes); point evaluation and DOF locations need only the element and the numbering.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
from skfem.assembly import Dofs
from skfem.mapping import MappingAffine


def reference_doflocs(mesh, elem, dofs: Dofs) -> np.ndarray:
    """DOF locations ``(2, N)`` of ``elem`` numbered by ``dofs`` on ``mesh``, as
    scikit-fem's bases compute them (without building a basis)."""
    mapped = MappingAffine(mesh).F(elem.doflocs.T)  # (2, nel, nlocal)
    out = np.zeros((mapped.shape[0], dofs.N))
    for i in range(mapped.shape[0]):
        for j in range(dofs.element_dofs.shape[0]):
            out[i, dofs.element_dofs[j]] = mapped[i, :, j]
    return out


class Numbering:
    """What :func:`~skfem_granular.fluid.points.evaluation_matrix` reads of a basis: its
    element and DOF numbering (no basis values); with a ``mesh``, also ``doflocs``."""

    def __init__(self, elem, dofs: Dofs, mesh=None):
        self.elem, self.element_dofs, self.N = elem, dofs.element_dofs, dofs.N
        self._where = (mesh, dofs)

    @cached_property
    def doflocs(self) -> np.ndarray:
        """DOF locations ``(2, N)``, as scikit-fem's basis on the mesh has them."""
        mesh, dofs = self._where
        if mesh is None:
            raise ValueError("doflocs: this numbering was made without a mesh")
        return reference_doflocs(mesh, self.elem, dofs)


def facet_dofs(dofs, mesh, facets: np.ndarray) -> np.ndarray:
    """The DOFs of ``dofs`` (a P1 or P2 field, scalar or vector) on ``facets``, sorted:
    what ``dofs.get_facet_dofs(facets).all()`` holds, without its per-call overhead (a
    mesh of 1000 grains asks for 1000 boundaries)."""
    vertices = np.unique(mesh.facets[:, facets])
    on_edges = (dofs.facet_dofs[:, facets].ravel() if dofs.facet_dofs.size
                else np.zeros(0, dtype=dofs.nodal_dofs.dtype))
    return np.sort(np.concatenate([dofs.nodal_dofs[:, vertices].ravel(), on_edges]))
