"""Moving particles on a fixed mesh: when to remesh, and moving fields onto a new mesh.

Between remeshes the fluid mesh keeps the particle outlines where they were
when it was built (see :mod:`skfem_granular.coupled.monolithic`). :func:`lag` measures
how far each particle's material outline has moved since then;
:func:`transfer` interpolates P2 velocities (and P1 pressures) onto the nodes
of a new mesh. New nodes in the region a particle has vacated lie just
outside the old mesh: they are snapped onto the nearest old element, whose
boundary values are the particle's rigid velocity there. Both BDF2 histories
``u_n`` and ``u_{n-1}`` must be transferred, or the scheme silently drops to
first order; :func:`transfer_histories` moves all of a coupled state's, on a
moving mesh each from its own configuration and projected divergence-free.
"""

from __future__ import annotations

import numpy as np

from ..fluid.points import PointLocator, evaluation_matrix
from ..fluid.projection import divergence_free_projection


def lag(centers_ref: np.ndarray, angles_ref: np.ndarray, centers: np.ndarray,
        angles: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Largest displacement ``(K,)`` of an outline point since the mesh was built.

    Translation of the centre plus rotation times the bounding radius.
    """
    shift = np.linalg.norm(np.asarray(centers) - np.asarray(centers_ref), axis=0)
    return shift + np.abs(np.asarray(angles) - np.asarray(angles_ref)) * np.asarray(radii)


class FieldTransfer:
    """Interpolation of P2/P1 fields from an old discretisation onto a new one.

    Parameters
    ----------
    old, new : TaylorHood
        Source and target discretisations.
    tol : float
        How far (in barycentric units of the nearest element) a new node may
        lie outside the old mesh before it is an error.
    """

    def __init__(self, old, new, tol: float = 1.0):
        loc = PointLocator(old.mesh)
        # numberings, not scikit-fem bases: a basis's quadrature values are not needed here
        nodes = new.numbering("scalar").doflocs
        cells, X = loc.locate(nodes, tol=tol, name="new mesh nodes")
        self._Eu = evaluation_matrix(old.numbering("scalar"), cells, X)
        vertices = new.numbering("pressure").doflocs
        nv = vertices.shape[1]
        if np.array_equal(nodes[:, :nv], vertices):  # P2 numbers the vertices first: found
            cells, X = cells[:nv], X[:, :nv]  # (each point is located on its own)
        else:
            cells, X = loc.locate(vertices, tol=tol, name="new mesh vertices")
        self._Ep = evaluation_matrix(old.numbering("pressure"), cells, X)
        self.new = new

    def velocity(self, u: np.ndarray) -> np.ndarray:
        """Velocity DOFs on the new mesh (interleaved x, y)."""
        out = np.empty(self.new.nu)
        out[0::2] = self._Eu @ u[0::2]
        out[1::2] = self._Eu @ u[1::2]
        return out

    def pressure(self, p: np.ndarray) -> np.ndarray:
        """Pressure DOFs on the new mesh."""
        return self._Ep @ p


def transfer_histories(state, old, new, *, old_prev=None, new_prev=None, project=None) -> dict:
    """The fluid histories of a :class:`~skfem_granular.coupled.state.CoupledState` moved
    from ``old`` onto ``new``: ``u_n``, ``du_n``, ``p_n`` at ``t_n``, ``u_prev``
    and ``du_prev`` at ``t_{n-1}``, as a dict of those fields (for
    ``dataclasses.replace``). Before the first step (``p_n`` None, a first mesh rebuilt
    at once) the pressure stays None.

    Parameters
    ----------
    state : CoupledState
        The state on ``old`` (not changed).
    old, new : TaylorHood
        The discretisations at ``t_n``.
    old_prev, new_prev : TaylorHood, optional
        Moving mesh: both meshes in their ``t_{n-1}`` configuration (the nodal values of
        ``u_{n-1}`` belong to where the nodes were then); default: the ``t_n`` ones.
    project : NavierStokesOperator, optional
        The new mesh's operator: project both histories onto its discretely
        divergence-free velocities, each in its own configuration
        (:func:`~skfem_granular.fluid.projection.divergence_free_projection`), so that the
        next step does not remove an interpolation's divergence with a pressure impulse.
    """
    s = state
    tr = FieldTransfer(old, new)
    u_n = tr.velocity(s.u_n)
    du_n = None if s.du_n is None else tr.velocity(s.du_n)
    p_n = None if s.p_n is None else tr.pressure(s.p_n)  # None: no step taken yet
    tr_prev = tr if old_prev is None else FieldTransfer(old_prev, new_prev)
    u_prev = None if s.u_prev is None else tr_prev.velocity(s.u_prev)
    du_prev = None if s.du_prev is None else tr_prev.velocity(s.du_prev)
    if project is not None:
        u_n = divergence_free_projection(project, u_n)
        if u_prev is not None:  # on the t_{n-1} configuration: its M and B only
            u_prev = divergence_free_projection(project, u_prev,
                                                space=None if old_prev is None else new_prev)
    return {"u_n": u_n, "du_n": du_n, "p_n": p_n, "p_prev": None, "u_prev": u_prev,
            "du_prev": du_prev}
