"""The discretely divergence-free velocity nearest to a given one (after an interpolation).

A velocity interpolated from another mesh is not divergence-free on the new one
(``B u != 0``). A BDF2 step started from it must remove that divergence in one
step: the pressure takes an impulse of the size ``divergence / dt``, which shows
as a spike in the forces on the particles and a jump in their velocities, larger
the smaller the step. :func:`divergence_free_projection` removes it beforehand:
the ``M``-orthogonal projection onto ``{v : B v = 0}`` with the boundary values
kept,

    min ||v - u||_M   subject to   B v = 0,   v = u on the Dirichlet DOFs,

one saddle-point solve ``[[M, B^T], [B, 0]] [v - u; q] = [0; -B u]`` on the free
DOFs. It changes ``u`` by the size of its divergence (for an interpolated field:
of the interpolation error) and leaves a divergence-free ``u`` unchanged.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse.linalg as spla


def divergence_free_projection(op, u: np.ndarray) -> np.ndarray:
    """``u`` projected onto the discretely divergence-free velocities of ``op``'s mesh.

    Parameters
    ----------
    op : NavierStokesOperator
        The operator whose mesh, ``M``, ``B`` and Dirichlet DOFs (kept at their values
        in ``u``) define the projection.
    u : (nu,) ndarray
        Velocity DOFs.

    Returns
    -------
    ndarray
        The projected velocity DOFs (a new array).

    Raises
    ------
    ValueError
        When ``u`` does not have ``op.space.nu`` finite entries.
    """
    sp_ = op.space
    u = np.asarray(u, dtype=float)
    if u.shape != (sp_.nu,) or not np.all(np.isfinite(u)):
        raise ValueError(f"u: must be {sp_.nu} finite velocity DOFs, got shape {u.shape}")
    J = op.reduced(op.matrix(sp_.M))
    r = np.concatenate([np.zeros(sp_.nu), sp_.B @ u])[op.free]
    x = np.concatenate([u, np.zeros(sp_.np_)])
    x[op.free] -= spla.splu(J.tocsc()).solve(r)
    return x[: sp_.nu]
