"""The moving mesh inside a coupled step: where the mesh is, and when to remesh.

:func:`step_geometry` builds the callback through which the corrector of one
step (``MonolithicCoupling.step(geometry=...)``) puts the mesh where its iterate
puts the particles; :func:`remesh_reason` is the rule that decides, before a
step, whether the moved mesh is still good enough. Both act on a
:class:`~skfem_granular.coupled.mesh_motion.MeshMotion`; the
:class:`~skfem_granular.coupled.mesh_keeper.MeshKeeper` owns it.
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


def step_geometry(motion, reference_space, state, bdf2, q_n, q_fixed, cores) -> Callable:
    """The mesh-motion callback of one step (:attr:`StepProblem.geometry`).

    The poses at the end of the step follow from the rigid velocities by the BDF2
    formula (or are ``q_fixed``, the DEM's, with contacts); the vertices follow the
    poses; the mesh velocity is the same BDF2 derivative of the vertex positions.

    Parameters
    ----------
    motion : MeshMotion
        The mesh's motion (vertex positions for poses).
    reference_space : TaylorHood
        The discretisation on the mesh as built.
    state : CoupledState
        The state the step starts from: its time, vertex positions (``nodes_n``,
        ``nodes_prev``) and poses at ``t_{n-1}`` (``q_prev``).
    bdf2 : BDF2
        The step's formula.
    q_n : (3, K) ndarray
        Poses at ``t_n``.
    q_fixed : (3, K) ndarray or None
        Poses at the end of the step when they are known beforehand (the DEM's).
    cores : CoreSizes
        The particles' bounding radii and outline edge lengths.

    Returns
    -------
    callable
        ``geometry(xi) -> (space, centres (2, K), mesh velocity DOFs)``, or None when
        the poses moved by less than :data:`ALE_POSE_TOL` of an edge since the last call.
        Raises ConvergenceError when the poses would invert a triangle (the step is
        then halved like an unconverged one).
    """
    nodes_n = state.nodes_n
    nodes_prev = nodes_n if state.nodes_prev is None else state.nodes_prev
    tol = ALE_POSE_TOL * float(cores.edge.min())
    used = {"q": None}

    def geometry(xi):
        q = q_fixed if q_fixed is not None else bdf2.solve(xi, q_n, state.q_prev)
        if used["q"] is not None:
            change = (np.abs(q[:2] - used["q"][:2]).max(axis=0)
                      + np.abs(q[2] - used["q"][2]) * cores.radius)
            if change.max() <= tol:
                return None
        used["q"] = q
        nodes = motion.positions(q)
        try:
            space = reference_space.moved(nodes)
        except ValueError as exc:  # an iterate would invert a triangle: a smaller step
            raise ConvergenceError(f"step at t={state.t:.6g}: {exc}") from exc
        return space, q[:2], space.vertex_field(bdf2.derivative(nodes, nodes_n, nodes_prev))

    return geometry


def remesh_reason(motion, state, moved, q, dt_ratio: float | None, cores,
                  remesh_travel: float) -> str | None:
    """Why to remesh the moving mesh now, or None.

    ``"travel"``: a particle has travelled ``remesh_travel`` radii (``moved``, per
    particle) from where its mesh was built; ``"angle"`` / ``"area"``: the mesh at
    ``state.nodes_n`` has its smallest angle or area ratio below :data:`ALE_MIN_ANGLE` /
    :data:`ALE_MIN_AREA_RATIO`; ``"ahead"``: it would after :data:`ALE_LOOK_AHEAD`
    steps, the poses ``q`` extrapolated from ``state.q_prev`` with ``dt_ratio`` (the
    largest step over the last one; None: no history, not checked). ``cores``: the
    particles' radii and outline edges (:class:`~.build.CoreSizes`).
    """
    radius, edge = cores.radius, cores.edge
    if np.any(moved > remesh_travel * radius):
        return "travel"
    if state.nodes_n is None:
        return None
    angle, ratio = mesh_quality(state.nodes_n, motion.t, motion.area_ref)
    if angle < ALE_MIN_ANGLE:
        return "angle"
    if ratio < ALE_MIN_AREA_RATIO:
        return "area"
    if dt_ratio is None:
        return None
    # checked only when that step moves a particle by more than a tenth of an outline
    # edge, or the mesh is already within 1.5x of the thresholds
    ahead = q + ALE_LOOK_AHEAD * (q - state.q_prev) * dt_ratio
    reach = lag(q[:2], q[2], ahead[:2], ahead[2], radius)
    if (np.all(reach < 0.1 * edge) and angle > 1.5 * ALE_MIN_ANGLE
            and ratio > 1.5 * ALE_MIN_AREA_RATIO):
        return None
    angle, ratio = mesh_quality(motion.positions(ahead), motion.t, motion.area_ref)
    return "ahead" if angle < ALE_MIN_ANGLE or ratio < ALE_MIN_AREA_RATIO else None
