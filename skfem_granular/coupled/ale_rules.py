"""The moving mesh inside a coupled step: where the mesh is, and when to remesh.

:func:`step_geometry` builds the callback through which the corrector of one
step (``MonolithicCoupling.step(geometry=...)``) puts the mesh where its iterate
puts the particles; :func:`remesh_reason` is the rule that decides, before a
step, whether the moved mesh is still good enough. Both act on a
:class:`~skfem_granular.coupled.mesh_motion.MeshMotion`; the
:class:`~skfem_granular.coupled.stepper.CoupledStepper` owns the state they read.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..fluid.errors import ConvergenceError
from .mesh_motion import mesh_quality
from .transfer import lag

#: Why a remesh happened (:func:`remesh_reason`).
REMESH_REASONS = ("travel", "angle", "area", "ahead")

#: Remesh when the smallest angle of the moved mesh falls below this (degrees).
ALE_MIN_ANGLE = 12.0

#: Remesh when a triangle has shrunk below this fraction of its built area (now, or at the
#: positions predicted for the end of the next step). A triangle in a closing gap shrinks
#: across the gap and stays a good triangle far below 0.3 of its area, so the angle rule
#: decides there; this bound only catches collapse.
ALE_MIN_AREA_RATIO = 0.1

#: The remesh rule looks this many (largest) steps ahead, the poses extrapolated from the
#: last two steps. One step: a corrector iterate that would still invert a triangle fails
#: its step (halved) rather than assembling on it.
ALE_LOOK_AHEAD = 1.0

#: Vertices of straight axis-parallel walls slide along them
#: (:func:`~skfem_granular.coupled.mesh_motion.sliding_wall_nodes`).
ALE_SLIDE_WALLS = True

#: The mesh follows the particles' poses from the corrector's iterates until they change
#: by less than this fraction of the outline edge length.
ALE_POSE_TOL = 1e-8


def step_geometry(motion, reference_space, nodes_n, nodes_prev, bdf2, q_n, q_prev, q_fixed,
                  radius, edge, t: float) -> Callable:
    """The mesh-motion callback of one step (see ``MonolithicCoupling.step``).

    The poses at the end of the step follow from the rigid velocities by the BDF2
    formula (or are ``q_fixed``, the DEM's, with contacts); the vertices follow the
    poses; the mesh velocity is the same BDF2 derivative of the vertex positions.

    Parameters
    ----------
    motion : MeshMotion
        The mesh's motion (vertex positions for poses).
    reference_space : TaylorHood
        The discretisation on the mesh as built.
    nodes_n, nodes_prev : (2, nv) ndarray
        Vertex positions at ``t_n`` and ``t_{n-1}`` (``nodes_prev`` unused when the
        step is backward Euler).
    bdf2 : (a0, a1, a2)
        The step's BDF2 (or backward-Euler, ``a2 = 0``) coefficients.
    q_n, q_prev : (3, K) ndarray
        Poses at ``t_n`` and ``t_{n-1}`` (``q_prev`` None for backward Euler).
    q_fixed : (3, K) ndarray or None
        Poses at the end of the step when they are known beforehand (the DEM's).
    radius, edge : (K,) ndarray
        Bounding radii and outline edge lengths of the particles.
    t : float
        Time at the start of the step (for messages).

    Returns
    -------
    callable
        ``geometry(xi) -> (space, centres (2, K), mesh velocity DOFs)``, or None when
        the poses moved by less than :data:`ALE_POSE_TOL` of an edge since the last call.
        Raises ConvergenceError when the poses would invert a triangle (the step is
        then halved like an unconverged one).
    """
    a0, a1, a2 = bdf2
    nodes_prev = nodes_n if nodes_prev is None else nodes_prev
    tol = ALE_POSE_TOL * float(edge.min())
    used = {"q": None}

    def geometry(xi):
        if q_fixed is not None:
            q = q_fixed
        else:
            q = (xi - a1 * q_n - (a2 * q_prev if q_prev is not None else 0.0)) / a0
        if used["q"] is not None:
            change = (np.abs(q[:2] - used["q"][:2]).max(axis=0)
                      + np.abs(q[2] - used["q"][2]) * radius)
            if change.max() <= tol:
                return None
        used["q"] = q
        nodes = motion.positions(q)
        try:
            space = reference_space.moved(nodes)
        except ValueError as exc:  # an iterate would invert a triangle: a smaller step
            raise ConvergenceError(f"step at t={t:.6g}: {exc}") from exc
        wv = a0 * nodes + a1 * nodes_n + (a2 * nodes_prev if a2 != 0.0 else 0.0)
        return space, q[:2], space.vertex_field(wv)

    return geometry


def remesh_reason(motion, nodes_n, moved, q, q_prev, dt_ratio: float | None, radius, edge,
                  remesh_travel: float) -> str | None:
    """Why to remesh the moving mesh now, or None.

    ``"travel"``: a particle has travelled ``remesh_travel`` radii (``moved``, per
    particle) from where its mesh was built; ``"angle"`` / ``"area"``: the mesh at
    ``nodes_n`` has its smallest angle or area ratio below :data:`ALE_MIN_ANGLE` /
    :data:`ALE_MIN_AREA_RATIO`; ``"ahead"``: it would after :data:`ALE_LOOK_AHEAD`
    steps, the poses ``q`` extrapolated from ``q_prev`` with ``dt_ratio`` (the largest
    step over the last one; None: no history, not checked).
    """
    if np.any(moved > remesh_travel * radius):
        return "travel"
    if nodes_n is None:
        return None
    angle, ratio = mesh_quality(nodes_n, motion.t, motion.area_ref)
    if angle < ALE_MIN_ANGLE:
        return "angle"
    if ratio < ALE_MIN_AREA_RATIO:
        return "area"
    if dt_ratio is None:
        return None
    # checked only when that step moves a particle by more than a tenth of an outline
    # edge, or the mesh is already within 1.5x of the thresholds
    ahead = q + ALE_LOOK_AHEAD * (q - q_prev) * dt_ratio
    reach = lag(q[:2], q[2], ahead[:2], ahead[2], radius)
    if (np.all(reach < 0.1 * edge) and angle > 1.5 * ALE_MIN_ANGLE
            and ratio > 1.5 * ALE_MIN_AREA_RATIO):
        return None
    angle, ratio = mesh_quality(motion.positions(ahead), motion.t, motion.area_ref)
    return "ahead" if angle < ALE_MIN_ANGLE or ratio < ALE_MIN_AREA_RATIO else None
