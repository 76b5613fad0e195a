"""Fill-reducing orderings of finite element systems, computed from the mesh.

SuperLU's own ordering (minimum degree on ``A + A^T``) treats every unknown
alone and is recomputed at every factorisation. On a Taylor-Hood system the
two velocity components at a node, and the pressure at a vertex, belong to
exactly the same elements. Two orderings here use the elements:

- :func:`minimum_degree`: minimum degree on the graph of those groups of
  unknowns ("nodes"), each group then numbered contiguously, which gives
  SuperLU dense supernodes at about the same fill (the default);
- :func:`nested_dissection`: recursive bisection of the elements at the
  median of their centroids, separators last; more fill, larger supernodes.

Measured on the paper's box with a moving disk (BDF2 Newton matrix,
SuperLU with static pivoting, median of 5, one run; benchmarks/fluid_step.py
reports the current figures):

=============  ==============  ============  ==============
unknowns       ordering        factor (s)    triangular solve (s)
=============  ==============  ============  ==============
8477           MMD_AT_PLUS_A   0.089         0.0035
8477           minimum_degree  0.062         0.0031
8477           nested dissect. 0.060         0.0034
77411          MMD_AT_PLUS_A   1.18          0.026
77411          minimum_degree  0.97          0.029
77411          nested dissect. 0.87          0.040
=============  ==============  ============  ==============

Time steps solve many times per factorisation, so the default is the
minimum degree on nodes. Either ordering depends only on the mesh and on
which unknowns are free: it is computed once per mesh and reused by every
factorisation on it (the symbolic analysis a direct solver would otherwise
redo each time).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

#: Elements per leaf subdomain of the nested dissection; 1-8 measured within noise.
LEAF_ELEMENTS = 4

#: Names accepted by :func:`fill_reducing_ordering`.
ORDERINGS = ("minimum_degree", "nested_dissection")


def element_incidence(element_dofs: list[np.ndarray], n: int) -> sp.csr_matrix:
    """Element-to-unknown incidence, ``(nelements, n)``, from blocks of element DOFs.

    Parameters
    ----------
    element_dofs : list of ndarray
        Arrays ``(k, nelements)`` of unknown indices per element (scikit-fem's
        ``basis.element_dofs``, shifted into one numbering); negative entries
        (eliminated unknowns) are skipped.
    n : int
        Number of unknowns.
    """
    dofs = np.vstack(element_dofs)
    nel = dofs.shape[1]
    rows = np.broadcast_to(np.arange(nel), dofs.shape).ravel()
    cols = dofs.ravel()
    keep = cols >= 0
    inc = sp.csr_matrix((np.ones(int(keep.sum()), dtype=np.int8), (rows[keep], cols[keep])),
                        shape=(nel, n))
    inc.data[:] = 1  # duplicates summed by the constructor
    return inc


def _postorder(depth: int) -> np.ndarray:
    """Postorder rank of every node of the complete binary tree of ``depth`` levels.

    Nodes are numbered level by level (heap order, root 0, children of ``j`` at
    ``2j + 1`` and ``2j + 2``).
    """
    nnode = 2 ** (depth + 1) - 1
    rank = np.empty(nnode, dtype=np.int64)
    stack, counter = [(0, False)], 0
    while stack:
        node, expanded = stack.pop()
        if expanded or node >= 2 ** depth - 1:  # children done, or a leaf
            rank[node] = counter
            counter += 1
        else:
            stack += [(node, True), (2 * node + 2, False), (2 * node + 1, False)]
    return rank


def nested_dissection(incidence: sp.spmatrix, centroids: np.ndarray,
                      leaf: int = LEAF_ELEMENTS) -> np.ndarray:
    """Permutation of the unknowns: subdomains first, their separators after them.

    The elements are bisected recursively at the median of their centroids
    along the longer side of each subdomain's bounding box; an unknown shared
    by elements of both halves belongs to that bisection's separator. Unknowns
    shared by many elements (rigid-body velocities of a particle, coupled to
    every element at its surface) therefore land in the separator where those
    elements part, as they should.

    Parameters
    ----------
    incidence : sparse matrix
        ``(nelements, n)`` element-to-unknown incidence (:func:`element_incidence`).
    centroids : ndarray
        ``(2, nelements)`` element centroids.
    leaf : int
        Bisection stops at about this many elements per subdomain.

    Returns
    -------
    ndarray
        ``perm`` of length ``n``: row ``i`` of the permuted system is unknown
        ``perm[i]``. Unknowns in no element come last.
    """
    inc = sp.csc_matrix(incidence)
    nel, n = inc.shape
    centroids = np.asarray(centroids, dtype=float)
    if centroids.shape != (2, nel):
        raise ValueError(f"centroids: shape {centroids.shape}, expected (2, {nel})")
    depth = max(0, int(np.ceil(np.log2(max(nel, 1) / max(leaf, 1)))))
    counts = np.diff(inc.indptr)
    has = counts > 0
    starts = inc.indptr[:-1][has]
    node = np.full(n, -1, dtype=np.int64)  # tree node (heap number) of each unknown
    dom = np.zeros(nel, dtype=np.int64)  # subdomain of each element within its level
    for level in range(depth):
        ndom = 2 ** level
        lo = np.full((2, ndom), np.inf)
        hi = np.full((2, ndom), -np.inf)
        for a in range(2):
            np.minimum.at(lo[a], dom, centroids[a])
            np.maximum.at(hi[a], dom, centroids[a])
        axis = np.argmax(hi - lo, axis=0)  # longer side of each subdomain
        key = centroids[axis[dom], np.arange(nel)]
        order = np.lexsort((key, dom))
        size = np.bincount(dom, minlength=ndom)
        first = np.concatenate(([0], np.cumsum(size)[:-1]))
        rank = np.empty(nel, dtype=np.int64)
        rank[order] = np.arange(nel) - first[dom[order]]
        parent = dom
        dom = 2 * dom + (rank >= size[dom] // 2)
        # unknowns touching both halves of one subdomain: its separator
        d = dom[inc.indices]
        dmin = np.minimum.reduceat(d, starts)
        dmax = np.maximum.reduceat(d, starts)
        split = np.zeros(n, dtype=bool)
        split[has] = dmin != dmax
        new = split & (node < 0)
        first_el = inc.indices[inc.indptr[:-1][new]]
        node[new] = (2 ** level - 1) + parent[first_el]
    rest = has & (node < 0)
    node[rest] = (2 ** depth - 1) + dom[inc.indices[inc.indptr[:-1][rest]]]
    rank = _postorder(depth)
    key = np.where(node >= 0, rank[np.maximum(node, 0)], rank.size)
    return np.argsort(key, kind="stable")


def unknown_groups(incidence: sp.spmatrix) -> np.ndarray:
    """Group number of every unknown: unknowns in exactly the same elements share one.

    Parameters
    ----------
    incidence : sparse matrix
        ``(nelements, n)`` element-to-unknown incidence.

    Returns
    -------
    ndarray
        ``(n,)`` group numbers ``0 .. ngroups - 1``; unknowns in no element
        get a group each.
    """
    inc = sp.csc_matrix(incidence)
    nel, n = inc.shape
    # two random 62-bit signatures per element; sums (wrapping in int64) identify element sets
    rng = np.random.default_rng(12345)
    w = rng.integers(1, 2**62, size=(2, nel), dtype=np.int64)
    counts = np.diff(inc.indptr)
    keys = np.zeros((3, n), dtype=np.int64)
    has = counts > 0
    starts = inc.indptr[:-1][has]
    for a in range(2):
        keys[a, has] = np.add.reduceat(w[a][inc.indices], starts)
    keys[2] = np.where(has, counts, -1 - np.arange(n))  # lonely unknowns stay apart
    # number the distinct key columns in lexicographic order (np.unique(axis=1) does the
    # same through a structured-dtype sort, 6x slower)
    order = np.lexsort(keys[::-1])
    sorted_keys = keys[:, order]
    first = np.r_[True, np.any(sorted_keys[:, 1:] != sorted_keys[:, :-1], axis=0)]
    groups = np.empty(n, dtype=np.int64)
    groups[order] = np.cumsum(first) - 1
    return groups


def minimum_degree(incidence: sp.spmatrix) -> np.ndarray:
    """Minimum degree ordering of the groups of unknowns, each group kept contiguous.

    The graph of the groups (:func:`unknown_groups`; adjacent when they share
    an element) is ordered by SuperLU's multiple minimum degree, which scipy
    exposes only through a factorisation: an incomplete factorisation that drops
    every off-diagonal entry of a diagonally dominant matrix with the graph's
    pattern gives its column permutation (the same as a complete factorisation's,
    at 0.4x the cost).

    Parameters
    ----------
    incidence : sparse matrix
        ``(nelements, n)`` element-to-unknown incidence.

    Returns
    -------
    ndarray
        ``perm`` of length ``n``: row ``i`` of the permuted system is unknown ``perm[i]``.
    """
    inc = sp.csr_matrix(incidence, dtype=float)
    n = inc.shape[1]
    groups = unknown_groups(inc)
    ng = int(groups.max()) + 1 if n else 0
    S = sp.csr_matrix((np.ones(n), (np.arange(n), groups)), shape=(n, ng))
    G_inc = inc @ S
    G_inc.data[:] = 1.0
    G = (G_inc.T @ G_inc).tocsc()
    G = (G + sp.identity(ng, format="csc") * (float(G.sum(axis=1).max()) + 1.0)).tocsc()
    lu = spla.spilu(G, drop_tol=np.inf, fill_factor=1.0, permc_spec="MMD_AT_PLUS_A",
                    diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))
    position = lu.perm_c  # group g is eliminated at position[g]
    return np.argsort(position[groups], kind="stable")


def fill_reducing_ordering(incidence: sp.spmatrix, centroids: np.ndarray,
                           method: str = "minimum_degree") -> np.ndarray:
    """Ordering of the unknowns by ``method`` (one of :data:`ORDERINGS`).

    Parameters
    ----------
    incidence : sparse matrix
        ``(nelements, n)`` element-to-unknown incidence.
    centroids : ndarray
        ``(2, nelements)`` element centroids (nested dissection only).
    method : str
        ``"minimum_degree"`` or ``"nested_dissection"``.
    """
    if method == "minimum_degree":
        return minimum_degree(incidence)
    if method == "nested_dissection":
        return nested_dissection(incidence, centroids)
    raise ValueError(f"ordering = {method!r}: must be one of {', '.join(map(repr, ORDERINGS))}")
