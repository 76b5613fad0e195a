"""Local repair of a moving triangle mesh: edge flips judged along its motion.

A mesh whose vertices follow moving particles keeps its connectivity; a few triangles in a
closing gap or a sheared layer go flat long before the rest of the mesh needs rebuilding.
:func:`flip_repair` swaps the diagonal of the quadrilateral that such a triangle forms
with a neighbour when that raises the smaller of the pair's smallest angles, judged over
several positions of the same vertices (where the mesh was, where it is, where it is
going), and only when both new triangles keep their orientation in every one of them.
Vertices, boundary edges and every other triangle stay as they are: a field on the
vertices and on the kept edges needs no transfer.

:func:`with_triangles` makes the repaired ``skfem.MeshTri`` with the named boundaries and
subdomains of the mesh it repairs.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import skfem
from numpy.typing import NDArray

from .quality import signed_areas


def _score(P: NDArray[np.float64], tri: NDArray[np.int64], sign: NDArray[np.float64],
           near: int, cap: float) -> NDArray[np.float64]:
    """``(2, n)``: for each triangle of ``tri`` ``(3, n)``, its smallest angle (degrees)
    over the first ``near`` configurations of ``P`` ``(m, 2, nv)``, at most ``cap``, and
    over all of them; ``-1`` where one is flat or turned over (signed area times
    ``sign`` not positive). Compared as pairs, first entry first."""
    q = P[:, :, tri]  # (m, 2, 3, n)
    e = q[:, :, [2, 0, 1]] - q[:, :, [1, 2, 0]]  # the edge opposite each vertex
    area = 0.5 * (e[:, 0, 2] * e[:, 1, 0] - e[:, 1, 2] * e[:, 0, 0])  # (b-a) x (c-b) / 2
    L2 = e[:, 0] ** 2 + e[:, 1] ** 2  # (m, 3, n)
    b2, c2 = L2[:, [1, 2, 0]], L2[:, [2, 0, 1]]
    cos = (b2 + c2 - L2) / np.maximum(2.0 * np.sqrt(b2 * c2), 1e-300)
    smallest = np.degrees(np.arccos(np.clip(cos.max(axis=1), -1.0, 1.0)))  # (m, n)
    smallest = np.where(area * sign <= 0.0, -1.0, smallest)
    return np.vstack([np.minimum(smallest[:near].min(axis=0), cap), smallest.min(axis=0)])


def _neighbours(t: NDArray[np.int64], nv: int) -> NDArray[np.int64]:
    """``(3, nt)``: the triangle across the edge opposite each local vertex (-1: none)."""
    nt = t.shape[1]
    a, b = t[[1, 2, 0]], t[[2, 0, 1]]  # row i: the edge opposite vertex i
    key = (np.minimum(a, b).astype(np.int64) * nv + np.maximum(a, b)).ravel()
    order = np.argsort(key, kind="stable")
    same = np.flatnonzero(key[order][1:] == key[order][:-1])
    nbr = np.full(3 * nt, -1, dtype=np.int64)
    first, second = order[same], order[same + 1]
    nbr[first], nbr[second] = second % nt, first % nt
    return nbr.reshape(3, nt)


def flip_repair(t: NDArray[np.int64], configurations: Sequence[NDArray[np.float64]],
                min_angle: float, *, near: int | None = None, max_flips: int | None = None
                ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Flip interior edges until no triangle is below ``min_angle`` in any configuration,
    or no flip helps.

    Parameters
    ----------
    t : (3, nt) int ndarray
        The triangles (not changed). Either orientation; the first configuration
        fixes each triangle's.
    configurations : sequence of (2, nv) ndarray
        Positions of the same vertices the mesh must be good at (for a moving mesh:
        where it was, where it is, where it is going).
    min_angle : float
        Degrees: a triangle whose smallest angle in some configuration is below this is
        repaired, by the flip of one of its edges that raises the smaller of the two new
        triangles' scores (smallest angle over the configurations) the most, if any does.
    near : int, optional
        The first ``near`` configurations come first (default: all of them): a flip must
        not lower the pair's smallest angle over those below ``min_angle`` (it may raise
        it), and among such flips the one that raises the smallest angle over all
        configurations the most is taken. (Judged over all at once, a flip that helps a
        configuration far ahead could spoil the one the mesh is in.)
    max_flips : int, optional
        At most this many flips (default: ten per triangle below ``min_angle``, and ten).

    Returns
    -------
    t : (3, nt) int ndarray
        The triangles after the flips: a flipped pair keeps its two column indices,
        every other column is unchanged.
    changed : (k,) int ndarray
        The columns that changed (sorted).
    """
    t = np.array(t, dtype=np.int64)
    P = np.asarray(np.stack([np.asarray(c, dtype=float) for c in configurations]))
    if P.ndim != 3 or P.shape[1] != 2 or P.shape[2] <= int(t.max()):
        raise ValueError(f"configurations: must be (2, nv) vertex positions with nv > "
                         f"{int(t.max())}, got shape {P.shape[1:]}")
    sign = np.sign(signed_areas(P[0], t))
    near = P.shape[0] if near is None else int(near)
    score = np.hstack([_score(P, t[:, k:k + 50_000], sign[k:k + 50_000], near, min_angle)
                       for k in range(0, t.shape[1], 50_000)])  # in bounded memory
    judge = (near, min_angle)
    bad = [int(e) for e in np.flatnonzero(score[1] < min_angle)]
    if not bad:
        return t, np.zeros(0, dtype=np.int64)
    nbr = _neighbours(t, P.shape[2])
    budget = 10 * len(bad) + 10 if max_flips is None else int(max_flips)
    changed: set[int] = set()
    while bad and budget > 0:
        e = bad.pop()
        if score[1, e] >= min_angle:
            continue
        best = _best_flip(P, t, nbr, sign, score, e, judge)
        if best is None:
            continue
        _flip(t, nbr, sign, score, e, *best)
        budget -= 1
        f = best[0]
        changed.update((e, f))
        # the pair, and their neighbours (whose best flip may have changed: Lawson's)
        bad.extend(int(k) for k in {e, f, *nbr[:, e], *nbr[:, f]}
                   if k >= 0 and score[1, k] < min_angle)
    return t, np.array(sorted(changed), dtype=np.int64)


def _best_flip(P, t, nbr, sign, score, e, judge):
    """The flip of an edge of triangle ``e`` that raises its pair's score (a pair, compared
    first entry first) the most: ``(f, i, new triangles (3, 2), their scores (2, 2))``, or
    None."""
    found = []
    for i in range(3):
        f = int(nbr[i, e])
        if f < 0:
            continue
        a, b, c = t[i, e], t[(i + 1) % 3, e], t[(i + 2) % 3, e]
        d = next(int(v) for v in t[:, f] if v != b and v != c)
        found.append((f, i, np.array([[a, a], [b, d], [d, c]], dtype=np.int64)))
    if not found:
        return None
    s = _score(P, np.hstack([new for *_, new in found]), sign[e], *judge)
    best, best_gain = None, None
    for k, (f, i, new) in enumerate(found):
        pair = s[:, 2 * k:2 * k + 2]
        gain = (pair[0].min(), pair[1].min())
        before = (min(score[0, e], score[0, f]), min(score[1, e], score[1, f]))
        if gain[0] < before[0] or (gain[0] == before[0] and gain[1] <= before[1] + 1e-9):
            continue  # not better, first entry first
        if best_gain is None or gain > best_gain:
            best, best_gain = (f, i, new, pair), gain
    return best


def _flip(t, nbr, sign, score, e, f, i, new, s) -> None:
    """Replace triangles ``e`` and ``f`` (sharing the edge opposite ``t[i, e]``) by
    ``new``, in place, with their neighbours."""
    a, b, c = t[i, e], t[(i + 1) % 3, e], t[(i + 2) % 3, e]
    d = new[1, 1]

    def across(tri, u, v):  # the neighbour of ``tri`` across its edge (u, v)
        k = next(k for k in range(3) if t[k, tri] != u and t[k, tri] != v)
        return int(nbr[k, tri])

    n_ca, n_ab = across(e, c, a), across(e, a, b)
    n_bd, n_dc = across(f, b, d), across(f, d, c)
    t[:, e], t[:, f] = new[:, 0], new[:, 1]
    nbr[:, e] = (n_bd, f, n_ab)  # (a, b, d): opposite a, b, d
    nbr[:, f] = (n_dc, n_ca, e)  # (a, d, c): opposite a, d, c
    for g, old, now in ((n_bd, f, e), (n_ca, e, f)):
        if g >= 0:
            nbr[:, g][nbr[:, g] == old] = now
    sign[f] = sign[e]
    score[:, e], score[:, f] = s[:, 0], s[:, 1]


def with_triangles(mesh: skfem.MeshTri, t: NDArray[np.int64],
                   p: NDArray[np.float64] | None = None) -> skfem.MeshTri:
    """``mesh`` with the triangles ``t`` (the same vertices and boundary edges, as after
    :func:`flip_repair`), its vertices at ``p`` (default: where they are), and its named
    boundaries and subdomains (by column: a flipped pair keeps its columns)."""
    p = mesh.p if p is None else np.asarray(p, dtype=float)
    new = skfem.MeshTri(p, np.asarray(t, dtype=np.int32), sort_t=False)
    if mesh.boundaries:
        nv = p.shape[1]
        keys = np.sort(new.facets, axis=0)
        key_new = keys[0].astype(np.int64) * nv + keys[1]
        order = np.argsort(key_new)
        boundaries = {}
        for name, facets in mesh.boundaries.items():
            old = np.sort(mesh.facets[:, facets], axis=0)
            want = old[0].astype(np.int64) * nv + old[1]
            at = order[np.searchsorted(key_new, want, sorter=order).clip(max=order.size - 1)]
            if not np.array_equal(key_new[at], want):
                raise ValueError(f"t: the boundary {name!r} lost an edge (flip_repair "
                                 "flips interior edges only)")
            boundaries[name] = at
        # the constructor's own fields, set here so that the facets are computed once
        new._boundaries = boundaries
    if mesh.subdomains:
        new._subdomains = dict(mesh.subdomains)
    return new
