"""The compiled pattern kernels against their definitions through numpy and scipy.

A new mesh builds its CSR patterns, scatter maps and SuperLU's first input with
counting sorts and merges (:mod:`skfem_granular.fluid.pattern_numba`,
:mod:`skfem_granular.fluid.factor_input_numba`); these must be the same arrays, bit
for bit, as the sorts and sparse operations they replace.
"""

import numpy as np
import pytest
import scipy.sparse as sp
from skfem import MeshTri

from skfem_granular.fluid.convection import element_pattern
from skfem_granular.fluid.geometry import scatter_pattern
from skfem_granular.fluid.space import TaylorHood
from skfem_granular.fluid.superlu import SuperLUSolver


def _unique_pattern(rows, cols, shape):
    """The definition: ``numpy.unique`` of the row-major keys, with the inverse."""
    keys = rows.ravel().astype(np.int64) * shape[1] + cols.ravel()
    unique, slot = np.unique(keys, return_inverse=True)
    indptr = np.concatenate(([0], np.cumsum(np.bincount(unique // shape[1],
                                                        minlength=shape[0]))))
    return slot, unique % shape[1], indptr


@pytest.fixture(scope="module")
def space():
    mesh = MeshTri.init_circle(3)  # unstructured enough: vertices of 4-8 triangles
    return TaylorHood(mesh)


def test_scatter_pattern_is_that_of_unique_keys():
    rng = np.random.default_rng(0)
    rows = rng.integers(0, 37, size=(50, 4, 5))
    cols = rng.integers(0, 23, size=(50, 4, 5))  # many duplicates, empty rows
    got = scatter_pattern(rows, cols, (40, 23))
    want = _unique_pattern(rows, cols, (40, 23))
    for g, w in zip(got, want, strict=True):
        assert g.dtype == np.int32
        np.testing.assert_array_equal(g, w)


def test_vector_element_pattern_is_that_of_its_entries(space):
    edofs = space.scalar_dofs.element_dofs  # (6, nel)
    nel = edofs.shape[1]
    # entry (e, i, c, j, d): row 2 edof_i + c, column 2 edof_j + d
    rows = 2 * edofs.T[:, :, None, None, None] + np.arange(2)[None, None, :, None, None]
    cols = 2 * edofs.T[:, None, None, :, None] + np.arange(2)[None, None, None, None, :]
    rows, cols = np.broadcast_arrays(rows, cols)
    assert rows.shape == (nel, 6, 2, 6, 2)
    n = 2 * (int(edofs.max()) + 1)
    slot, indices, indptr = element_pattern(edofs)
    want = _unique_pattern(rows, cols, (n, n))
    np.testing.assert_array_equal(slot, want[0])
    np.testing.assert_array_equal(indices, want[1])
    np.testing.assert_array_equal(indptr, want[2])


def test_velocity_block_positions_in_the_convection_pattern(space):
    from skfem_granular.fluid.pattern_numba import positions_in

    indices, indptr = space.convection.pattern
    K = sp.csr_matrix(space.K("symmetric"))
    K.sum_duplicates()
    pos = np.empty(K.indices.size, dtype=np.int64)
    assert positions_in(indptr, indices, K.indptr, K.indices, pos)
    rows = np.repeat(np.arange(K.shape[0]), np.diff(K.indptr))
    keys = np.repeat(np.arange(K.shape[0]), np.diff(indptr)) * K.shape[0] + indices
    np.testing.assert_array_equal(pos, np.searchsorted(keys, rows * K.shape[0] + K.indices))
    # an entry outside the wider pattern is reported, not placed
    missing = np.setdiff1d(np.arange(K.shape[0]), indices[indptr[0]:indptr[1]])[0]
    outside = sp.csr_matrix(([1.0], ([0], [missing])), shape=K.shape)
    assert not positions_in(indptr, indices, outside.indptr, outside.indices,
                            np.empty(1, dtype=np.int64))

    # the velocity block added into convection values there: numpy's gather, add and
    # scatter, bit for bit (what the Oseen matrix of a split step is made of)
    from skfem_granular.fluid.pattern_numba import add_at_positions

    rng = np.random.default_rng(1)
    wide = rng.standard_normal(indices.size)
    expected = wide.copy()
    expected[pos] = K.data + expected[pos]
    add_at_positions(wide, pos, K.data)
    np.testing.assert_array_equal(wide, expected)


def _scipy_input(A, nu, perm, Mp, delta):
    """SuperLU's input through scipy: ``D A D - reg``, rows gathered, columns relabelled,
    sorted (the construction the compiled passes replace)."""
    n = A.shape[0]
    scale = SuperLUSolver._pressure_scale(A, nu)
    rows = np.repeat(np.arange(n), np.diff(A.indptr))
    data = (scale[rows] * A.data) * scale[A.indices]
    S = sp.csr_matrix((data, A.indices, A.indptr), shape=A.shape)
    S.eliminate_zeros()
    vmax = float(np.median(np.abs(S.diagonal()[:nu])))
    if Mp is None:
        reg = sp.diags(np.r_[np.zeros(nu), np.full(n - nu, delta * vmax)])
    else:
        Mps = sp.csr_matrix(Mp) * scale[-1] ** 2
        reg = sp.block_diag([sp.csr_matrix((nu, nu)), Mps * (delta * vmax / abs(Mps).max())])
    S = (S - reg).tocsr()
    P = S[perm]
    inv = np.empty_like(perm)
    inv[perm] = np.arange(n)
    CT = sp.csc_matrix((P.data, inv[P.indices], P.indptr), shape=A.shape[::-1])
    CT.sort_indices()
    return CT


@pytest.mark.parametrize("with_mass", [False, True])
def test_superlu_input_is_scipys_bit_for_bit(with_mass):
    rng = np.random.default_rng(3)
    nu, npr = 40, 12
    n = nu + npr
    Auu = sp.random(nu, nu, density=0.2, random_state=4) + sp.identity(nu) * 3.0
    Bt = sp.random(nu, npr, density=0.3, random_state=5) * 7.0
    A = sp.bmat([[Auu, Bt], [Bt.T, None]], format="csr")
    A.sum_duplicates()
    A.data[rng.random(A.nnz) < 0.05] = 0.0  # stored zeros, dropped by the scaling
    Mp = (sp.random(npr, npr, density=0.3, random_state=6) + sp.identity(npr)).tocsr()
    Mp = Mp + Mp.T
    perm = rng.permutation(n)
    solver = SuperLUSolver()
    solver.nu = nu
    solver._static = True
    got = solver._regularised(A, perm, Mp if with_mass else None)
    want = _scipy_input(A, nu, perm, Mp if with_mass else None, solver.delta)
    np.testing.assert_array_equal(got.indptr, want.indptr)
    np.testing.assert_array_equal(got.indices, want.indices)
    np.testing.assert_array_equal(got.data, want.data)
    # and the factors solve the system
    x = rng.standard_normal(n)
    solver.factorize(A, nu, ordering=perm, **({"Mp": Mp} if with_mass else {}))
    np.testing.assert_allclose(solver.solve(A @ x), x, rtol=1e-8, atol=1e-10)


def test_saddle_matrix_is_that_of_scipys_block_stacking():
    from helpers import annulus

    import skfem_granular as sg
    from skfem_granular.fluid.boundary import DirichletData
    from skfem_granular.fluid.operator import NavierStokesOperator

    space = TaylorHood(annulus(1e-3, 2e-3, 16, 32, (2e-4) ** 2))
    op = NavierStokesOperator(space, sg.Fluid(1000.0, 1e-3),
                              DirichletData(space, {"inner": (0.0, 1e-2), "outer": (0.0, 0.0)}),
                              convection=True)
    rng = np.random.default_rng(7)
    moved = space.moved(1.01 * space.mesh.p + 2e-5)  # stretched and shifted
    for o in (op, op.moved(moved)):
        x = rng.standard_normal(o.space.N)
        w = rng.standard_normal(o.space.nu)
        J = o.jacobian(x, 1.5e3, w_mesh=w)
        # the construction through scipy's sparse algebra, block by block
        kern = o.space.convection
        N = kern.jacobian(x[: o.space.nu]) - kern.jacobian(w, newton=False)
        N.data *= 1000.0
        A = o.velocity_block(1.5e3) + N
        want = sp.bmat([[A, o.space.B.T], [o.space.B, None]], format="csr")
        want.sum_duplicates()  # B's stored entries kept, as scipy's sum keeps A + N's nonzeros
        J.sum_duplicates()
        np.testing.assert_array_equal(J.indptr, want.indptr)
        np.testing.assert_array_equal(J.indices, want.indices)
        np.testing.assert_array_equal(J.data, want.data)
        # and the linear part alone
        L = o.linear_matrix(o.velocity_block(1.5e3))
        ref = sp.bmat([[o.velocity_block(1.5e3), o.space.B.T], [o.space.B, None]], format="csr")
        ref.sum_duplicates()
        L.sum_duplicates()
        for got, expected in ((L.indptr, ref.indptr), (L.indices, ref.indices),
                              (L.data, ref.data)):
            np.testing.assert_array_equal(got, expected)


def test_facet_dofs_are_scikit_fems():
    """The boundary DOFs read off the numbering (one call per grain on a many-grain mesh)
    are scikit-fem's ``get_facet_dofs(...).all()``, sorted, for every field of the space."""
    from skfem_granular.fluid.numbering import facet_dofs

    m = MeshTri.init_circle(4).with_boundaries({"left": lambda x: x[0] < 0,
                                                      "top": lambda x: x[1] > 0.3})
    space = TaylorHood(m)
    for name, facets in m.boundaries.items():
        for dofs in (space.velocity_dofs, space.pressure_dofs, space.scalar_dofs):
            want = np.sort(dofs.get_facet_dofs(facets).all())
            got = facet_dofs(dofs, m, facets)
            assert got.dtype == want.dtype and np.array_equal(got, want), name
