"""Size-field meshes around many particles (kind "field", the default for more than
one particle): quality, gaps resolved, outlines kept, size, determinism, bad input,
the scene default, and the single particle's graded mesh (the same on both paths, its
size, quality and area)."""

import numpy as np
import pytest

import meshing
from meshing import field, geometry

BOX = (0.0, 0.0, 20e-3, 10e-3)
R = 0.5e-3          # shadow circumradius of the collapse's hexagons
CORE = 0.8          # core ratio
DL = 0.2e-3


def hexagon(c, r=CORE * R, ang=0.0):
    th = ang + 2.0 * np.pi * np.arange(6) / 6
    return np.vstack([c[0] + r * np.cos(th), c[1] + r * np.sin(th)])


def honeycomb(nx, ny, x0=5e-3):
    """Cores of hexagons whose shadows tile the floor and each other (all touching)."""
    a = R * np.sqrt(3.0) / 2.0
    return [hexagon((x0 + i * 1.5 * R, a + 2 * a * j + (a if i % 2 else 0.0)))
            for i in range(nx) for j in range(ny)]


def block(n, spacing=1.15e-3, origin=(0.8e-3, 3.0e-3), seed=1, jitter=0.3):
    """The collapse's initial n x n block of cores (random orientations, seeded)."""
    rng = np.random.default_rng(seed)
    out = []
    for j in range(n):
        for i in range(n):
            ang = rng.uniform(-jitter, jitter)
            out.append(hexagon((origin[0] + i * spacing, origin[1] + j * spacing), ang=ang))
    return out


def scattered(n, box, seed=0):
    rng = np.random.default_rng(seed)
    x0, y0, x1, y1 = box
    C, out = [], []
    while len(out) < n:
        c = rng.uniform([x0 + 0.6e-3, y0 + 0.6e-3], [x1 - 0.6e-3, y1 - 0.6e-3])
        if all(np.hypot(*(c - q)) > 2 * R for q in C):
            C.append(c)
            out.append(hexagon(c, ang=rng.uniform(0, np.pi)))
    return out


SPREAD_BOX = (0.0, 0.0, 30e-3, 10e-3)
SPREAD = [hexagon((2.6e-3 + i * 2 * R, R * np.sqrt(3) / 2)) for i in range(25)]
SQUARE = [hexagon((3e-3 + i * 2 * R, R * np.sqrt(3) / 2 * (1 + 2 * j)))
          for i in range(5) for j in range(5)]

#: cases where the guaranteed bounds (min angle >= 20, R/2r <= 3) hold
CLEAR = {
    "single particle": ((0.0, 0.0, 3e-3, 11e-3),
                        [np.vstack([1.5e-3 + R * np.cos(2 * np.pi * np.arange(24) / 24),
                                    5.5e-3 + R * np.sin(2 * np.pi * np.arange(24) / 24)])],
                        None),
    "5 x 5 block": (BOX, block(5), DL),
    "10 x 10 block": (BOX, block(10, spacing=0.95e-3, origin=(5e-3, 0.6e-3)), DL),
    "100 scattered": ((0.0, 0.0, 20e-3, 20e-3), scattered(100, (0.0, 0.0, 20e-3, 20e-3)), DL),
}
#: shadows touching each other and the floor (cores 0.8): gaps 0.87 and 0.43 outline edges
TOUCHING = {
    "honeycomb 3 x 3 on the floor": (BOX, honeycomb(3, 3), DL),
    "honeycomb 5 x 5 on the floor": (BOX, honeycomb(5, 5), DL),
    "25 in one layer on the floor": (SPREAD_BOX, SPREAD, DL),
    "5 x 5 stacked columns": (BOX, SQUARE, DL),
}
ALL = {**CLEAR, **TOUCHING}


@pytest.fixture(scope="module")
def built():
    return {name: meshing.build("field", d, p, delta_l=dl) for name, (d, p, dl) in ALL.items()}


def joining_edges(value):
    """Mesh edges joining two different outlines or an outline and the wall."""
    m = value.mesh
    comp = np.full(m.p.shape[1], -1)
    comp[np.unique(m.facets[:, m.boundaries["wall"]])] = 0
    for k, idx in enumerate(value.particle_nodes):
        comp[idx] = k + 1
    c = comp[m.facets]
    return np.flatnonzero((c[0] >= 0) & (c[1] >= 0) & (c[0] != c[1]))


def outline_chain(value, k, P):
    """Particle k's boundary facets: a closed chain over P's edges through every vertex
    of P (edges facing a narrow gap may carry extra nodes, nothing else); returns the
    number of extra nodes."""
    mesh = value.mesh
    idx = value.particle_nodes[k]
    np.testing.assert_array_equal(mesh.p[:, idx], P)
    f = mesh.facets[:, mesh.boundaries[f"particle{k}"]]
    nodes = np.unique(f)
    assert np.all(np.isin(idx, nodes))
    # every node twice in the facets (a closed chain), facets on P's edges, total length
    assert np.all(np.bincount(f.ravel(), minlength=mesh.p.shape[1])[nodes] == 2)
    d, _ = geometry.edge_distance(P, mesh.p[:, nodes])
    assert np.abs(d).max() <= 1e-12 * np.ptp(P)
    mid = 0.5 * (mesh.p[:, f[0]] + mesh.p[:, f[1]])
    assert np.abs(geometry.edge_distance(P, mid)[0]).max() <= 1e-12 * np.ptp(P)
    length = np.hypot(*(mesh.p[:, f[0]] - mesh.p[:, f[1]])).sum()
    assert length == pytest.approx(geometry.outline_lengths(P).sum(), rel=1e-12)
    return nodes.size - idx.size


def check_outlines_and_gaps(value, outlines):
    mesh = value.mesh
    s = meshing.mesh_stats(mesh)
    assert s.n_inverted == 0 and s.max_aspect <= 3.0
    for k, P in enumerate(outlines):
        outline_chain(value, k, P)
    # no element touches two outlines (or an outline and the wall): every gap has
    # at least two elements across and an interior node
    assert joining_edges(value).size == 0
    np.testing.assert_array_equal(np.sort(mesh.boundary_facets()), np.sort(np.concatenate(
        [mesh.boundaries["wall"]] + [mesh.boundaries[f"particle{k}"]
                                     for k in range(len(outlines))])))
    return s


@pytest.mark.parametrize("name", list(CLEAR))
def test_quality_bounds(built, name):
    d, parts, dl = CLEAR[name]
    s = check_outlines_and_gaps(built[name], [geometry.subdivide(P, dl) for P in parts])
    assert s.min_angle >= 20.0


@pytest.mark.parametrize("name", list(TOUCHING))
def test_touching_grains_resolved(built, name):
    """Gaps of 0.87 (core-core) and 0.43 (core-floor) outline edges: no element across,
    outlines intact (edges facing the gaps split), min angle >= 20 degrees (measured
    23.8-28.1; 18.4-19.1 before the gap edges were split), aspect <= 3."""
    d, parts, dl = TOUCHING[name]
    s = check_outlines_and_gaps(built[name], [geometry.subdivide(P, dl) for P in parts])
    assert s.min_angle >= 20.0


def test_narrow_gaps_are_lined_at_a_third_of_their_width(built):
    """Honeycomb: the flat faces 0.173 mm apart carry outline nodes at most 0.058 mm
    apart, the bottom faces 0.087 mm over the floor at most 0.029 mm (274 nodes added
    to 108 outline nodes); the 5 x 5 block in the air, with gaps of 0.35-0.46 mm, only
    where they are narrower than 2 delta_l (88 added to 300)."""
    value = built["honeycomb 3 x 3 on the floor"]
    mesh = value.mesh
    a = R * np.sqrt(3) / 2
    f = mesh.facets[:, mesh.boundaries["particle0"]]        # column 0, bottom core
    y = mesh.p[1, f]
    L = np.hypot(*(mesh.p[:, f[0]] - mesh.p[:, f[1]]))
    top = np.all(np.isclose(y, a + CORE * a), axis=0)
    bottom = np.all(np.isclose(y, a - CORE * a), axis=0)
    assert top.sum() >= 7 and L[top].max() <= 0.2 * np.sqrt(3) * R / 3 * (1 + 1e-9)
    assert bottom.sum() >= 14 and L[bottom].max() <= 0.1 * np.sqrt(3) * R / 3 * (1 + 1e-9)
    parts = [geometry.subdivide(P, DL) for P in CLEAR["5 x 5 block"][1]]
    assert sum(outline_chain(built["5 x 5 block"], k, P) for k, P in enumerate(parts)) < 100
    assert sum(outline_chain(value, k, geometry.subdivide(P, DL))
               for k, P in enumerate(TOUCHING["honeycomb 3 x 3 on the floor"][1])) > 250


def crossings(mesh, a, b, n=400):
    """Distinct elements met along the straight segment a -> b (ends excluded)."""
    s = np.linspace(0.0, 1.0, n + 2)[1:-1]
    x = np.asarray(a)[:, None] + s * (np.asarray(b) - np.asarray(a))[:, None]
    return np.unique(mesh.element_finder()(x[0], x[1])).size


def test_gap_between_flat_faces_has_two_elements_across(built):
    """Honeycomb: flat faces of vertically stacked cores 0.173 mm apart (less than
    delta_l), the core's bottom face 0.087 mm above the floor."""
    mesh = built["honeycomb 3 x 3 on the floor"].mesh
    a = R * np.sqrt(3) / 2
    x = 5e-3 + 0.03e-3                                  # column 0, off the nodes
    top_of_first = a + CORE * a
    bottom_of_second = 3 * a - CORE * a
    assert bottom_of_second - top_of_first == pytest.approx(0.2 * np.sqrt(3) * R, rel=1e-12)
    assert crossings(mesh, (x, top_of_first), (x, bottom_of_second)) >= 2
    assert crossings(mesh, (x, 0.0), (x, a - CORE * a)) >= 2


def test_cluster_keeps_a_fine_region_that_hugs_it(built):
    """Inside the honeycomb the edges stay at the outline's size or below (measured:
    mean 0.31, largest 1.51 outline edges); 6 mm from the cluster they have grown to
    8.2 outline edges on average (sigma = 1.2)."""
    mesh = built["honeycomb 5 x 5 on the floor"].mesh
    L = np.hypot(*(mesh.p[:, mesh.facets[0]] - mesh.p[:, mesh.facets[1]]))
    mid = 0.5 * (mesh.p[:, mesh.facets[0]] + mesh.p[:, mesh.facets[1]])
    inner = (mid[0] > 5.2e-3) & (mid[0] < 7.8e-3) & (mid[1] < 3.9e-3)
    assert L[inner].mean() <= 0.7 * DL and L[inner].max() <= 2.0 * DL
    far = np.hypot(mid[0] - 14e-3, mid[1] - 7e-3) < 1e-3
    assert L[far].mean() > 5 * DL


def test_deterministic():
    d, parts, dl = TOUCHING["honeycomb 3 x 3 on the floor"]
    a, b = meshing.field_mesh(d, parts, delta_l=dl), meshing.field_mesh(d, parts, delta_l=dl)
    np.testing.assert_array_equal(a.p, b.p)
    np.testing.assert_array_equal(a.t, b.t)


def test_size_against_the_group_mesh_and_growth():
    """Collapse at t = 0: the default mesh has 0.62 of the group mesh's DOFs (measured
    12748 against 20603); sigma = 1.5 (Eq. 4 for these cores) has fewer still."""
    parts = block(5)

    def dofs(kind, **kw):
        s = meshing.mesh_stats(meshing.build(kind, BOX, parts, delta_l=DL, **kw))
        return 2 * s.n_p2_nodes + s.n_vertices

    f, g, eq4 = dofs("field"), dofs("group"), dofs("field", sigma=1.5)
    assert f <= 0.65 * g
    assert eq4 < 0.85 * f


def test_spread_layer_costs_more_than_a_block():
    """The aim was <= 1.2 x; measured 2.20 x (1.39 x before the gap edges were
    split: the fine layer follows every exposed core, and the 25 floor gaps of 0.087 mm
    are lined at a third of their width): recorded, not met (docs/meshing.md)."""
    def dofs(parts):
        s = meshing.mesh_stats(meshing.build("field", SPREAD_BOX, parts, delta_l=DL))
        return 2 * s.n_p2_nodes + s.n_vertices

    ratio = dofs(SPREAD) / dofs([P + np.array([[5e-3], [0.0]]) for P in block(5)])
    assert 2.0 < ratio < 2.4


def test_remesh_keeps_the_rule():
    parts = block(3)
    value = meshing.build("field", BOX, parts, delta_l=DL)
    assert value.recipe.kind == "field"
    assert value.recipe.options == {"sigma": None, "delta_l": DL,
                                    "max_elements": field.MAX_FIELD_ELEMENTS, "relax_rounds": 0}
    moved = [P + np.array([[1e-3], [-2.5e-3]]) for P in parts]
    again = meshing.remesh(value, moved)
    fresh = meshing.build("field", BOX, moved, delta_l=DL)
    np.testing.assert_array_equal(again.mesh.p, fresh.mesh.p)
    np.testing.assert_array_equal(again.mesh.t, fresh.mesh.t)
    assert again.recipe.kind == "field"
    assert meshing.mesh_stats(again).min_angle >= 20.0


def test_bad_input():
    parts = block(2)
    with pytest.raises(ValueError, match=r"^delta_l = 0.0002, sigma = None: the size field "
                                         r"would give about .* triangles, more than "
                                         r"max_elements = 500; use a larger delta_l"):
        meshing.field_mesh(BOX, parts, delta_l=DL, max_elements=500)
    a = CORE * R * np.sqrt(3) / 2                  # cores 1 um apart: lined at 0.33 um
    close = [hexagon((5e-3, 5e-3)), hexagon((5e-3, 5e-3 + 2 * a + 1e-6))]
    with pytest.raises(ValueError, match=r"^delta_l = 0.0002, sigma = None: 2608 outline nodes "
                                         r"with the narrow gaps lined exceed max_elements = "
                                         r"1000; use a larger delta_l"):
        meshing.field_mesh((0.0, 0.0, 10e-3, 10e-3), close, delta_l=DL, max_elements=1000)
    with pytest.raises(ValueError, match=r"max_elements: must be an integer >= 100"):
        meshing.field_mesh(BOX, parts, delta_l=DL, max_elements=10)
    overlap = [hexagon((5e-3, 5e-3)), hexagon((5.5e-3, 5e-3))]
    with pytest.raises(ValueError, match=r"^particles\[0\] and particles\[1\] overlap"):
        meshing.field_mesh(BOX, overlap, delta_l=DL)
    for s in (1.0, 0.9):
        with pytest.raises(ValueError, match=r"^sigma: growth factor must be in \(1, 1.6\]"):
            meshing.field_mesh(BOX, parts, sigma=s, delta_l=DL)
    with pytest.raises(ValueError, match=r"particles: field_mesh needs at least one"):
        meshing.field_mesh(BOX, [], delta_l=DL)
    for msg in (str(e) for e in _errors(parts)):
        assert "\n" not in msg


def _errors(parts):
    out = []
    for kw in ({"max_elements": 500}, {"sigma": 1.0}):
        try:
            meshing.field_mesh(BOX, parts, delta_l=DL, **kw)
        except ValueError as exc:
            out.append(exc)
    assert len(out) == 2
    return out


def test_scene_default_is_graded_for_one_particle_and_field_for_more():
    from skfem_granular.coupled.build import build_mesh
    from skfem_granular.dem import DEMSystem
    from skfem_granular.scene import MeshSpec, Scene

    def cores(sc):
        dem = DEMSystem.in_box([p.to_dem() for p in sc.particles], sc.domain,
                               sc.wall_thickness, law=sc.contact_law)
        return dem.core_outlines()

    assert MeshSpec().kind == "auto"
    col, grp = Scene.bundled("collapse"), Scene.bundled("collapse_group")
    v, g = build_mesh(col, cores(col)), build_mesh(grp, cores(grp))
    assert v.recipe.kind == "field" and g.recipe.kind == "group"
    sv, sg = meshing.mesh_stats(v), meshing.mesh_stats(g)
    assert 2 * sv.n_p2_nodes + sv.n_vertices <= 2 * sg.n_p2_nodes + sg.n_vertices
    from dataclasses import replace

    sp = Scene.bundled("single_particle")
    one = build_mesh(replace(sp, mesh=MeshSpec()), cores(sp))
    assert one.recipe.kind == "graded"
    with pytest.raises(ValueError, match=r"mesh.kind = 'hex': must be 'auto', 'field', "
                                         r"'graded', 'uniform' or 'group'"):
        MeshSpec(kind="hex")


#: vertices and triangles of the single particle's graded mesh (main at 2924d56, before
#: the size-field mesh, and today: the same bits on one machine). The bits themselves depend on the
#: CPU: numpy's vectorised sin/cos differ in the last bit between AVX-512 and AVX2 builds,
#: and Triangle's output follows (a sha256 recorded on one machine failed on an AMD EPYC
#: without AVX-512, where 2924d56 and this code give the same bits as each other).
SINGLE_COUNTS = (198, 338)


def test_single_particle_graded_mesh_is_the_same_on_both_paths():
    from skfem_granular.coupled.build import build_mesh
    from skfem_granular.dem import DEMSystem
    from skfem_granular.scene import Scene

    sc = Scene.bundled("single_particle")
    dem = DEMSystem.in_box([p.to_dem() for p in sc.particles], sc.domain, sc.wall_thickness,
                           law=sc.contact_law)
    direct = meshing.graded_mesh(sc.domain, dem.core_outlines())
    built = build_mesh(sc, dem.core_outlines()).mesh
    np.testing.assert_array_equal(built.p, direct.p)
    np.testing.assert_array_equal(built.t, direct.t)
    nv, nt = direct.p.shape[1], direct.t.shape[1]
    # the counts of the reference mesh, up to the platform's round-off in Triangle's input
    assert abs(nv - SINGLE_COUNTS[0]) <= 0.02 * SINGLE_COUNTS[0]
    assert abs(nt - SINGLE_COUNTS[1]) <= 0.02 * SINGLE_COUNTS[1]
    # what the platform cannot move: the fluid's area (the box less the core polygon, by
    # the shoelace formula) to round-off, and Triangle's angle bound (34.5 deg measured)
    x, y = direct.p[:, direct.t]
    areas = 0.5 * ((x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]))
    core = np.asarray(dem.core_outlines()[0])
    polygon = 0.5 * abs(np.dot(core[0], np.roll(core[1], -1))
                        - np.dot(core[1], np.roll(core[0], -1)))
    x0, y0, x1, y1 = sc.domain
    assert areas.min() > 0
    assert abs(areas.sum() - ((x1 - x0) * (y1 - y0) - polygon)) <= 1e-12 * (x1 - x0) * (y1 - y0)
    assert meshing.mesh_stats(direct).min_angle >= 30.0


#: pore flux (m^2/s per unit depth) of the honeycomb case (validation.pore_flux) on the field
#: mesh with delta_l = 6.25 um (191625 DOFs; delta_l = 12.5 um is 0.072 % above it;
#: benchmarks/results/mesh_accuracy.json)
PORE_FLUX_REFERENCE = 1.802973e-09


def test_pore_flux_through_a_touching_honeycomb():
    """Acceptance (b): touching 3 x 3 honeycomb on the floor, slow flow through the
    pores, steady Stokes on the default mesh (delta_l = 0.2 mm): pore flux within 1 %
    of the converged reference (measured +0.53 %, 10378 DOFs; +5.9 % before the outline
    edges along the gaps were split; the uniform 0.2 / 0.1 mm meshes +8.6 / +1.2 %)."""
    from skfem_granular.validation import pore_flux

    cores = pore_flux.honeycomb()
    value = meshing.build("field", pore_flux.BOX, cores, delta_l=DL)
    q, _ = pore_flux.line_fluxes(value, cores)
    assert len(q) == 4
    assert abs(sum(q[:-1]) / PORE_FLUX_REFERENCE - 1.0) <= 0.01


def test_moving_split_outlines_keeps_the_extra_nodes_on_the_edges():
    """move_particles puts the nodes added along gap edges on the moved edges."""
    d, parts, dl = TOUCHING["honeycomb 3 x 3 on the floor"]
    value = meshing.build("field", d, parts, delta_l=dl)
    th = 0.02
    rot = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    moved = [rot @ (P - P.mean(axis=1, keepdims=True)) + P.mean(axis=1, keepdims=True)
             + np.array([[0.0], [5e-6]]) for P in parts]
    out = meshing.move_particles(value, moved)
    for k, P in enumerate(moved):
        assert outline_chain(out, k, geometry.subdivide(P, dl)) > 0
    assert not meshing.remesh_needed(out)


@pytest.mark.slow
def test_forces_on_a_moving_block_match_a_fine_mesh():
    """Acceptance (a): steady Stokes, 3 x 3 cores moving down at 1 mm/s in the closed
    box; each grain's force on the default mesh within 0.5 % of the uniform mesh at
    delta_l / 2 (measured 0.125 %, Eq. 4's sigma = 1.5 0.440 %; 0.468 and 0.736 % before
    the outline edges along gaps narrower than 2 delta_l were split)."""
    from skfem_granular.fluid import Fluid, solve_steady

    parts = [hexagon((8.85e-3 + i * 1.15e-3, 4.0e-3 + j * 1.15e-3))
             for j in range(3) for i in range(3)]
    fluid = Fluid(density=1000.0, viscosity=1e-3)

    def forces(value):
        vel = {"wall": (0.0, 0.0), **{f"particle{k}": (0.0, -1e-3) for k in range(9)}}
        flow = solve_steady(value.mesh, fluid, vel)
        return np.array([flow.force(f"particle{k}") for k in range(9)])

    ref = forces(meshing.build("uniform", BOX, parts, delta_l=DL / 2, h=DL / 2))
    err = {s: np.hypot(*(forces(meshing.build("field", BOX, parts, delta_l=DL, sigma=s))
                         - ref).T) / np.hypot(*ref.T) for s in (None, 1.5)}
    assert err[None].max() <= 2e-3
    assert err[None].max() < err[1.5].max() <= 5e-3


def test_gap_spacing_sets_the_lining():
    """``gap_spacing = 1``: the honeycomb's flat faces 0.173 mm apart carry outline nodes
    at most one gap width apart (0.173 mm, against 0.058 at the default third), the
    bottom faces 0.087 mm over the floor at most 0.087 mm; fewer nodes, the same
    quality bounds, no element across a gap, and remeshes keep the spacing."""
    d, parts, dl = TOUCHING["honeycomb 3 x 3 on the floor"]
    value = meshing.build("field", d, parts, delta_l=dl, gap_spacing=1.0)
    default = meshing.build("field", d, parts, delta_l=dl)
    mesh = value.mesh
    a = R * np.sqrt(3) / 2
    f = mesh.facets[:, mesh.boundaries["particle0"]]
    y = mesh.p[1, f]
    L = np.hypot(*(mesh.p[:, f[0]] - mesh.p[:, f[1]]))
    top = np.all(np.isclose(y, a + CORE * a), axis=0)
    bottom = np.all(np.isclose(y, a - CORE * a), axis=0)
    assert L[top].max() <= 0.2 * np.sqrt(3) * R * (1 + 1e-9)
    assert L[bottom].max() <= 0.1 * np.sqrt(3) * R * (1 + 1e-9)
    assert L[bottom].max() > 0.1 * np.sqrt(3) * R / 3 * (1 + 1e-9)   # coarser than 1/3
    assert mesh.p.shape[1] < 0.8 * default.mesh.p.shape[1]
    s = check_outlines_and_gaps(value, [geometry.subdivide(P, dl) for P in parts])
    assert s.min_angle >= 20.0
    assert value.recipe.options["gap_spacing"] == 1.0
    moved = [P + np.array([[1e-3], [0.0]]) for P in parts]
    again = meshing.remesh(value, moved)
    fresh = meshing.build("field", d, moved, delta_l=dl, gap_spacing=1.0)
    np.testing.assert_array_equal(again.mesh.p, fresh.mesh.p)
    for bad in (0.05, 0, -1.0, "1", True):
        with pytest.raises(ValueError, match="gap_spacing"):
            meshing.build("field", d, parts, delta_l=dl, gap_spacing=bad)
