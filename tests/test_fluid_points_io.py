"""Point evaluation, interpolation between meshes and VTU/PVD output of a flow.

References: fields that P2/P1 represent exactly (round-off), the P2
interpolation order h^3 for a smooth field, the vorticity 2 omega of a
rigid rotation, and byte-identical files after a failed write.
"""

import hashlib
import os
import re
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest
from helpers import annulus, box, regular_polygon
from skfem import Basis, ElementTriP2, MeshTri

import skfem_granular as sg
from skfem_granular.fluid.points import PointLocator, evaluation_matrix
from skfem_granular.io import PVDSeries, atomic_write, write_vtu

EPS = np.finfo(float).eps
MU = 0.7
#: Coefficients of a cubic stream function psi = sum c_ij x^i y^j (i + j <= 3).
PSI = {(3, 0): 0.3, (2, 1): -0.8, (1, 2): 0.5, (0, 3): 0.2, (2, 0): 0.4, (1, 1): -0.6,
       (0, 2): 0.9, (1, 0): 0.25, (0, 1): -0.35}


def quadratic_velocity(x, y):
    """u = (d psi/dy, -d psi/dx): a divergence-free quadratic field."""
    ux = sum(c * j * x**i * y ** (j - 1) for (i, j), c in PSI.items() if j > 0)
    uy = -sum(c * i * x ** (i - 1) * y**j for (i, j), c in PSI.items() if i > 0)
    return ux + 0 * x, uy + 0 * y


def linear_pressure(x, y):
    """grad p = mu lap u; lap u = (lap psi_y, -lap psi_x) is constant for a cubic psi."""
    c = PSI
    lap_psi_x = 6 * c[(3, 0)] + 2 * c[(1, 2)]   # d/dx of lap psi
    lap_psi_y = 2 * c[(2, 1)] + 6 * c[(0, 3)]   # d/dy of lap psi
    return MU * (lap_psi_y * x - lap_psi_x * y)


HEX = regular_polygon(6, 0.3, center=(0.5, 0.5))


def outside_hexagon(pts, margin):
    """Points farther than ``margin`` outside the hexagonal hole."""
    r = pts - 0.5
    ang = 2 * np.pi * (np.arange(6) + 0.5) / 6  # outward normals of the 6 faces
    proj = np.cos(ang)[:, None] * r[0] + np.sin(ang)[:, None] * r[1]
    return proj.max(axis=0) > 0.3 * np.cos(np.pi / 6) + margin


@pytest.fixture(scope="module")
def exact_flow():
    """Stokes in the unit box minus a hexagon, Dirichlet data of an exact P2/P1 solution."""
    mesh = box(0.0, 0.0, 1.0, 1.0, 0.004, hole=HEX)
    bc = {"wall": quadratic_velocity, "particle0": quadratic_velocity}
    return sg.solve_steady(mesh, sg.Fluid(1.0, MU), bc)


def test_point_values_reproduce_exact_p2_p1_fields(exact_flow):
    rng = np.random.default_rng(1)
    pts = rng.uniform(0.0, 1.0, (2, 3000))
    pts = pts[:, outside_hexagon(pts, 1e-6)]
    u = exact_flow.velocity(pts)
    ref = np.array(quadratic_velocity(*pts))
    scale = np.abs(ref).max()
    assert np.abs(u - ref).max() < 1e3 * EPS * scale  # measured 1.4e-14
    # closed domain: the pressure is the exact one shifted to zero mean. The
    # solver stops iterative refinement at a relative residual of 1e-13; the
    # saddle-point system amplifies it in the pressure by up to ~1e4.
    p = exact_flow.pressure(pts)
    pe = linear_pressure(*pts)
    shift = p - pe
    assert np.ptp(shift) < 1e-9 * np.abs(pe).max()  # measured 6.5e-11 / 2.2
    w = np.asarray(exact_flow.space.Mp.sum(axis=0)).ravel()
    pv = linear_pressure(*exact_flow.mesh.p)
    assert shift.mean() == pytest.approx(-(w @ pv) / w.sum(), abs=1e-9 * np.abs(pe).max())


def test_points_just_outside_are_snapped_onto_the_boundary(exact_flow):
    """Points 1e-9 outside the hole or the box are moved to the nearest element."""
    a, b = HEX[:, :-1], HEX[:, 1:]
    mid = (a + b) / 2
    n_out = (mid - 0.5) / np.linalg.norm(mid - 0.5, axis=0)  # out of the fluid: into the hole
    d = 1e-9
    pts = np.hstack([mid - d * n_out, [[0.3, 1.0 + d, -d], [-d, 0.6, 0.7]]])
    cells, X = exact_flow.locator.locate(pts)
    P = exact_flow.mesh.p[:, exact_flow.mesh.t[:, cells]]
    snapped = P[:, 0] + (P[:, 1] - P[:, 0]) * X[0] + (P[:, 2] - P[:, 0]) * X[1]
    assert np.all(X >= 0) and np.all(X.sum(axis=0) <= 1 + 1e-15)
    assert np.abs(snapped - pts).max() < 2 * d
    u = exact_flow.velocity(pts)
    np.testing.assert_allclose(u, np.array(quadratic_velocity(*snapped)), rtol=0,
                               atol=1e3 * EPS)


def test_snapping_near_a_small_finely_meshed_particle():
    """A 32-gon of radius 1e-3 in the unit box: elements near it are ~2e-4 wide.

    1e-9 of the mesh's size is 5e-6 of those elements, beyond the relative
    tolerance; it is snapped by the absolute one (1e-9 times the diameter).
    """
    hole = regular_polygon(32, 1e-3, center=(0.5, 0.5))
    loc = PointLocator(box(0.0, 0.0, 1.0, 1.0, 0.01, hole=hole))
    assert loc.abs_tol == pytest.approx(1e-9 * np.sqrt(2))
    mid = (hole[:, :1] + hole[:, 1:2]) / 2
    into_hole = (0.5 - mid) / np.linalg.norm(0.5 - mid)
    cells, X = loc.locate(mid + 1e-9 * into_hole)
    P = loc.mesh.p[:, loc.mesh.t[:, cells]]
    snapped = P[:, 0] + (P[:, 1] - P[:, 0]) * X[0] + (P[:, 2] - P[:, 0]) * X[1]
    assert np.linalg.norm(snapped - mid) < 1e-9 * np.sqrt(2)
    with pytest.raises(ValueError, match="lies outside the mesh"):
        loc.locate(mid + 1e-8 * into_hole)


@pytest.mark.parametrize("point", [(0.5, 0.5), (1.5, 0.2), (0.5 + 0.3 * np.cos(np.pi / 6) - 1e-3,
                                                            0.5)])
def test_points_clearly_outside_raise_and_name_the_point(exact_flow, point):
    pts = np.array([[0.2, point[0], 0.8], [0.2, point[1], 0.8]])
    msg = re.escape(f"points[:, 1] = ({point[0]:.6g}, {point[1]:.6g}) lies outside the mesh")
    with pytest.raises(ValueError, match=msg):
        exact_flow.velocity(pts)
    with pytest.raises(ValueError, match=msg):
        exact_flow.pressure(pts)


@pytest.mark.parametrize("bad", [np.zeros((3, 2)), np.zeros((2, 2, 2)), [[0.1, 0.2]],
                                 np.array([[np.nan], [0.5]]), np.array([[0.5], [np.inf]]),
                                 "abc", None])
def test_malformed_points_raise(exact_flow, bad):
    with pytest.raises(ValueError, match="^points"):
        exact_flow.velocity(bad)
    with pytest.raises(ValueError, match="^points"):
        exact_flow.pressure(bad)


def test_single_point_and_empty_input(exact_flow):
    x = np.array([0.1, 0.15])
    np.testing.assert_allclose(exact_flow.velocity(x)[:, 0], quadratic_velocity(*x), atol=1e-14)
    assert exact_flow.velocity(np.zeros((2, 0))).shape == (2, 0)
    assert exact_flow.pressure(np.zeros((2, 0))).shape == (0,)


def sliver_mesh(m=40):
    """A large triangle above y = 0 joined by slivers to a fine grid below y = -0.01.

    The 48 element centroids nearest to a point just above y = 0 all belong
    to the fine grid, none to the large triangle that contains it.
    """
    fine = MeshTri.init_tensor(np.linspace(-0.5, 0.5, m + 1), np.linspace(-0.1, -0.01, 10))
    p = fine.p
    top = np.flatnonzero(np.isclose(p[1], -0.01))
    top = top[np.argsort(p[0, top])]
    A, B, C = p.shape[1] + np.arange(3)
    P = np.hstack([p, [[-1.0, 1.0, 0.0], [0.0, 0.0, 2.0]]])
    t = np.vstack([fine.t.T, [[A, B, C], [A, top[-1], B]],
                   [[A, top[i], top[i + 1]] for i in range(top.size - 1)]])
    return MeshTri(P, t.T)


def test_locator_finds_a_large_element_among_many_small_ones():
    mesh = sliver_mesh()
    basis = Basis(mesh, ElementTriP2())
    x, y = basis.doflocs
    f = 1 + 2 * x - y + 3 * x * y - x**2 + 0.5 * y**2  # any quadratic is exact in P2
    pts = np.array([[0.0, 0.3, -0.2, 0.05], [1e-3, 0.5, 1e-6, -0.05]])
    cells, X = PointLocator(mesh).locate(pts)
    P = mesh.p[:, mesh.t[:, cells]]
    e1, e2 = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    area = np.abs(e1[0] * e2[1] - e1[1] * e2[0]) / 2
    assert np.all(area[:3] == 2.0)  # the large triangle (-1, 0), (1, 0), (0, 2)
    assert area[3] == pytest.approx(0.5 * (1 / 40) * (0.09 / 9))  # a fine-grid cell
    back = P[:, 0] + (P[:, 1] - P[:, 0]) * X[0] + (P[:, 2] - P[:, 0]) * X[1]
    assert np.abs(back - pts).max() < 10 * EPS
    val = evaluation_matrix(basis, cells, X) @ f
    xp, yp = pts
    exact = 1 + 2 * xp - yp + 3 * xp * yp - xp**2 + 0.5 * yp**2
    np.testing.assert_allclose(val, exact, rtol=0, atol=1e3 * EPS)


# interpolation between meshes --------------------------------------------------------


def potential_flow(x, y):
    """u = grad(e^x sin y): smooth, not polynomial, an exact Stokes solution with p = 0."""
    return np.exp(x) * np.sin(y), np.exp(x) * np.cos(y)


def unit_square(n):
    m = MeshTri.init_tensor(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1))
    return m.with_boundaries({"wall": m.boundary_facets()})


def _order(e):
    e = np.asarray(e)
    return np.log2(e[:-1] / e[1:])


def test_interpolation_onto_another_mesh_converges_at_order_three():
    """Flow on structured meshes A (h = 1/n), evaluated at the P2 DOFs of an unstructured mesh B.

    Max-norm error of P2 at arbitrary points: h^3 (interpolation and the
    Taylor-Hood solution); P1 pressure: h^2.
    """
    space_b = sg.TaylorHood(box(0.0, 0.0, 1.0, 1.0, 0.001))
    pts = space_b.sb.doflocs
    exact = np.array(potential_flow(*pts))
    err_solve, err_interp, err_p = [], [], []
    for n in (4, 8, 16, 32):
        flow = sg.solve_steady(unit_square(n), sg.Fluid(1.0, 1.0), {"wall": potential_flow})
        err_solve.append(np.abs(flow.velocity(pts) - exact).max())
        err_p.append(np.abs(flow.pressure(pts)).max())
        # the nodal interpolant alone
        sp_ = flow.space
        fx, fy = potential_flow(*sp_.velocity_doflocs)
        flow.x[: sp_.nu] = np.where(sp_.component == 0, fx, fy)
        err_interp.append(np.abs(flow.velocity(pts) - exact).max())
    # measured orders: solve 2.95 2.91 2.83, interpolant 2.96 2.97 2.99, pressure 2.0
    assert np.all(_order(err_interp) > 2.9), err_interp
    assert np.all(_order(err_solve) > 2.7), err_solve
    assert np.all(_order(err_p) > 1.9), err_p
    assert err_solve[-1] < 1e-5


def test_numberings_are_the_bases_dof_locations_without_building_a_basis():
    """``TaylorHood.numbering`` gives what a field transfer reads of a basis, bit for bit,
    on a mesh as built and moved (ALE), and builds no basis doing so."""
    space = sg.TaylorHood(box(0.0, 0.0, 1.0, 1.0, 0.05, hole=HEX))
    p = space.mesh.p
    moved = space.moved(p + 0.01 * np.sin(7.0 * p[::-1]))
    for sp_ in (space, moved):
        numbered = {f: sp_.numbering(f) for f in ("scalar", "pressure")}
        for n in numbered.values():
            n.doflocs  # noqa: B018 - computed here, before any basis exists
        assert not sp_.has_bases
        for field, basis in (("scalar", sp_.sb), ("pressure", sp_.pb)):
            n = numbered[field]
            assert np.array_equal(n.doflocs, basis.doflocs)
            assert np.array_equal(n.element_dofs, basis.element_dofs) and n.N == basis.N
    with pytest.raises(ValueError, match="field = 'vector'"):
        space.numbering("vector")


def test_a_field_transfer_builds_no_basis_and_moves_exact_fields_exactly():
    from skfem_granular.coupled.transfer import FieldTransfer

    old = sg.TaylorHood(box(0.0, 0.0, 1.0, 1.0, 0.04))
    new = sg.TaylorHood(box(0.0, 0.0, 1.0, 1.0, 0.03))
    tr = FieldTransfer(old, new)
    assert not old.has_bases and not new.has_bases
    # a quadratic velocity and a linear pressure are P2/P1 fields: moved to round-off
    u_old = np.empty(old.nu)
    ux, uy = quadratic_velocity(*old.velocity_doflocs)
    u_old[:] = np.where(old.component == 0, ux, uy)
    ux, uy = quadratic_velocity(*new.velocity_doflocs)
    np.testing.assert_allclose(tr.velocity(u_old), np.where(new.component == 0, ux, uy),
                               atol=1e3 * EPS)
    np.testing.assert_allclose(tr.pressure(linear_pressure(*old.mesh.p)),
                               linear_pressure(*new.mesh.p), atol=1e3 * EPS)
    # the vertices are located once, as the P2 nodes they are: the same values as a
    # location of the vertices on their own, bit for bit
    cells, X = PointLocator(old.mesh).locate(new.mesh.p, tol=1.0)
    p_old = np.cos(3.0 * old.mesh.p[0]) * old.mesh.p[1]
    alone = evaluation_matrix(old.numbering("pressure"), cells, X) @ p_old
    assert np.array_equal(tr.pressure(p_old), alone)


# output ------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def rotation():
    """Rigid rotation u = omega e_z x r of the fluid between two co-rotating polygons."""
    omega = 0.75
    mesh = annulus(1.0, 2.0, 16, 24, 0.05)
    spin = sg.RigidMotion(omega=omega)
    return omega, sg.solve_steady(mesh, sg.Fluid(1.0, 1.0), {"inner": spin, "outer": spin})


def test_save_writes_fields_that_meshio_reads_back(rotation, tmp_path):
    omega, flow = rotation
    path = tmp_path / "out" / "flow.vtu"
    flow.space.release_bases()
    flow.save(path)
    assert not flow.space.has_bases  # built for the frame, released after it
    m = meshio.read(path)
    n = flow.space.sb.N
    assert m.points.shape == (n, 3)
    assert set(m.point_data) == {"velocity", "pressure", "speed", "vorticity"}
    v = m.point_data["velocity"]
    assert v.shape == (n, 3) and np.all(v[:, 2] == 0)
    for k in ("pressure", "speed", "vorticity"):
        assert m.point_data[k].shape == (n,)
    # values: velocity omega x r, speed |omega| r, vorticity 2 omega, constant pressure
    x, y = m.points[:, 0], m.points[:, 1]
    np.testing.assert_allclose(v[:, 0], -omega * y, atol=1e3 * EPS)
    np.testing.assert_allclose(v[:, 1], omega * x, atol=1e3 * EPS)
    np.testing.assert_allclose(m.point_data["speed"], omega * np.hypot(x, y), atol=1e3 * EPS)
    np.testing.assert_allclose(m.point_data["vorticity"], 2 * omega, rtol=1e-12)
    assert np.abs(m.point_data["pressure"]).max() < 1e3 * EPS
    # quadratic triangles in VTK order: nodes 3, 4, 5 are the midpoints of edges 01, 12, 20
    c = m.cells_dict["triangle6"]
    P = m.points
    for k, (i, j) in zip((3, 4, 5), ((0, 1), (1, 2), (2, 0)), strict=True):
        np.testing.assert_allclose(P[c[:, k]], (P[c[:, i]] + P[c[:, j]]) / 2, atol=1e-15)
    # counter-clockwise vertices
    e1, e2 = P[c[:, 1]] - P[c[:, 0]], P[c[:, 2]] - P[c[:, 0]]
    assert np.all(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] > 0)


def test_saved_pressure_is_the_p1_field_at_p2_nodes(exact_flow, tmp_path):
    exact_flow.save(tmp_path / "exact.vtu")
    m = meshio.read(tmp_path / "exact.vtu")
    p = m.point_data["pressure"]
    shift = exact_flow.pressure(m.points[:, :2].T) - linear_pressure(*m.points[:, :2].T)
    np.testing.assert_allclose(p, linear_pressure(*m.points[:, :2].T) + shift.mean(),
                               atol=1e-9 * np.abs(p).max())


def _digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_pvd_series_index_and_atomic_frames(rotation, tmp_path):
    omega, flow = rotation
    times = [0.0, 0.1, 0.25]
    pvd = tmp_path / "series" / "flow.pvd"
    with PVDSeries(pvd) as series:
        files = [series.write(t, flow.save) for t in times]
        before = {f.name: _digest(f) for f in files}
        index = pvd.read_text()

        def crash(path):  # a partial file, then the simulation dies
            with open(path, "w") as fh:
                fh.write("<VTKFile partial")
            raise RuntimeError("simulated crash")

        with pytest.raises(RuntimeError, match="simulated crash"):
            series.write(0.5, crash)
        # earlier frames and the index untouched, no partial or temporary file left
        assert {f.name: _digest(f) for f in files} == before
        assert pvd.read_text() == index
        assert sorted(os.listdir(pvd.parent)) == sorted([pvd.name, *before])
        last = series.write(0.5, flow.save)  # the run goes on after the failure
    root = ET.parse(pvd).getroot()
    assert root.tag == "VTKFile" and root.get("type") == "Collection"
    ds = root.find("Collection").findall("DataSet")
    assert [float(d.get("timestep")) for d in ds] == [*times, 0.5]
    assert [d.get("file") for d in ds] == [f.name for f in [*files, last]]
    for d in ds:
        m = meshio.read(pvd.parent / d.get("file"))
        np.testing.assert_allclose(m.point_data["vorticity"], 2 * omega, rtol=1e-12)
    with pytest.raises(ValueError, match="t = nan"):
        PVDSeries(pvd).write(float("nan"), flow.save)


def test_output_files_are_readable_by_others(rotation, tmp_path):
    """mkstemp files are 0600; the renamed output must follow the umask like open()."""
    _, flow = rotation
    flow.save(tmp_path / "a.vtu")
    (tmp_path / "b.txt").write_text("x")
    mode = (tmp_path / "b.txt").stat().st_mode & 0o777
    assert (tmp_path / "a.vtu").stat().st_mode & 0o777 == mode


def test_unwritable_output_paths_raise_naming_the_path(rotation, tmp_path):
    _, flow = rotation
    blocker = tmp_path / "somefile"
    blocker.write_text("not a directory")
    for target in (blocker / "x.vtu", blocker / "sub" / "x.vtu"):
        with pytest.raises(ValueError, match=re.escape(str(target))):
            flow.save(target)
        with pytest.raises(ValueError, match=re.escape(str(target))):
            write_vtu(target, np.zeros((2, 3)), {"triangle": np.array([[0, 1, 2]])})
        with pytest.raises(ValueError, match=re.escape(str(target))):
            atomic_write(target, lambda tmp: None)
    with pytest.raises(ValueError, match=re.escape(str(blocker / "x.pvd"))):
        PVDSeries(blocker / "x.pvd")
    with pytest.raises(ValueError, match="must end in '.pvd'"):
        PVDSeries(tmp_path / "x.vtu")
    for name in ("x.vtk", "x"):  # meshio would write VTU XML under any name
        with pytest.raises(ValueError, match="must end in '.vtu'"):
            flow.save(tmp_path / name)
        assert not (tmp_path / name).exists()
    (tmp_path / "dir.vtu").mkdir()
    with pytest.raises(ValueError, match="is a directory"):
        flow.save(tmp_path / "dir.vtu")
    assert blocker.read_text() == "not a directory"


def test_failed_vtu_write_keeps_the_earlier_frame(rotation, tmp_path, monkeypatch):
    """meshio writing half a VTU, then failing (a full disk): the earlier file of that name
    stays byte for byte and no temporary file is left; the write went to one."""
    from helpers import fail_midway, partial_names

    _, flow = rotation
    path = tmp_path / "flow_00000.vtu"
    flow.save(path)
    before = _digest(path)
    written = fail_midway(monkeypatch, meshio, "write", lambda filename, *a: filename,
                          data=b"<VTKFile partial")
    for save in (lambda: flow.save(path),
                 lambda: write_vtu(path, np.zeros((2, 3)), {"triangle": np.array([[0, 1, 2]])})):
        with pytest.raises(OSError, match="No space left"):
            save()
        assert _digest(path) == before
        assert partial_names(tmp_path) == []
    assert [p.parent for p in written] == [tmp_path] * 2
    assert all(p.name.startswith(".partial-flow_00000-") for p in written)
