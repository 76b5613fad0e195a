"""Property-based tests: DEM polygon overlap geometry and the scene parser.

Overlap (:func:`skfem_granular.dem.overlap.overlap_geometry`, and the numba
kernel when installed) on irregular convex polygons at particle scale and
offset from the origin: symmetric in its arguments, never larger than the
smaller polygon, zero when the bounding circles are apart, the polygon's own
area for identical polygons and the inner area for a contained polygon.

Scene parser (:meth:`Scene.from_dict`, :meth:`Scene.from_toml`): random valid
scenes parse and keep their values; a random invalid number in any numeric
field gives a one-line ValueError naming the field.
"""

import json
import math
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from skfem_granular.dem import Polygon, overlap_numba, stable_time_step
from skfem_granular.dem.overlap import EPS_PARALLEL, overlap_geometry
from skfem_granular.dem.particles import pad_outlines
from skfem_granular.scene import Scene

BACKENDS = ["numpy"] + (["numba"] if overlap_numba.AVAILABLE else [])


# ====================================================================== overlap
def overlap_area(A, B, backend="numpy") -> float:
    """Overlap area of two ``(2, n)`` counter-clockwise outlines."""
    V, count = pad_outlines([np.asarray(A, float), np.asarray(B, float)])
    if backend == "numba":
        g = overlap_numba.overlap_pairs_numba(V, count, np.array([0]), np.array([1]))
    else:
        g = overlap_geometry(V[:1], V[1:])
    return float(g.area[0])


@st.composite
def convex_polygons(draw, scale=None, center=None):
    """Irregular strictly convex polygon: points on a rotated ellipse at random angles.

    ``scale`` (size) and the centre offset range over particle sizes in metres
    and over unit sizes; the centre is up to 10 sizes away from the origin.
    """
    n = draw(st.integers(3, 16))
    w = np.array(draw(st.lists(st.floats(0.25, 1.0), min_size=n, max_size=n)))
    phi = draw(st.floats(0.0, 2 * np.pi)) + np.concatenate([[0.0], np.cumsum(w[:-1])]) * (
        2 * np.pi / w.sum()
    )
    if scale is None:
        scale = draw(st.sampled_from([1e-3, 1.0]))
    r = draw(st.floats(0.2, 1.0)) * scale
    aspect = draw(st.floats(0.3, 1.0))
    rot = draw(st.floats(0.0, 2 * np.pi))
    x, y = r * np.cos(phi), aspect * r * np.sin(phi)
    c, s = np.cos(rot), np.sin(rot)
    if center is None:
        center = (draw(st.floats(-10.0, 10.0)) * scale, draw(st.floats(-10.0, 10.0)) * scale)
    V = np.vstack([c * x - s * y + center[0], s * x + c * y + center[1]])
    return Polygon(V).vertices  # validates: strictly convex, counter-clockwise


@st.composite
def polygon_pairs(draw):
    """Two polygons of one scale, near each other (overlapping, touching or apart)."""
    scale = draw(st.sampled_from([1e-3, 1.0]))
    A = draw(convex_polygons(scale=scale))
    cA = Polygon(A).centroid
    d = draw(st.floats(0.0, 2.5)) * scale
    a = draw(st.floats(0.0, 2 * np.pi))
    B = draw(convex_polygons(scale=scale, center=cA + d * np.array([np.cos(a), np.sin(a)])))
    return A, B, scale


@pytest.mark.parametrize("backend", BACKENDS)
@settings(max_examples=80, deadline=None)
@given(polygon_pairs())
def test_overlap_symmetric_and_bounded(backend, pair):
    A, B, scale = pair
    a, b = overlap_area(A, B, backend), overlap_area(B, A, backend)
    # near-collinear edges are snapped to collinear: area moves by ~EPS_PARALLEL * size^2
    snap = 10 * EPS_PARALLEL * (2 * scale) ** 2
    assert a == pytest.approx(b, rel=1e-10, abs=snap)
    assert 0.0 <= a <= min(Polygon(A).area, Polygon(B).area) * (1 + 1e-10)


@pytest.mark.parametrize("backend", BACKENDS)
@settings(max_examples=60, deadline=None)
@given(polygon_pairs(), st.floats(1e-6, 1.0), st.floats(0.0, 2 * np.pi))
def test_overlap_zero_when_bounding_circles_apart(backend, pair, gap, direction):
    A, B, _ = pair
    PA, PB = Polygon(A), Polygon(B)
    # move B so that the bounding circles are apart by gap * (rA + rB)
    dist = (PA.bounding_radius + PB.bounding_radius) * (1.0 + gap)
    target = PA.centroid + dist * np.array([np.cos(direction), np.sin(direction)])
    B = B + (target - PB.centroid)[:, None]
    assume(np.hypot(*(Polygon(B).centroid - PA.centroid)) > PA.bounding_radius + PB.bounding_radius)
    assert overlap_area(A, B, backend) == 0.0
    assert overlap_area(B, A, backend) == 0.0


@pytest.mark.parametrize("backend", BACKENDS)
@settings(max_examples=60, deadline=None)
@given(convex_polygons())
def test_overlap_of_identical_polygons_is_their_area(backend, A):
    assert overlap_area(A, A.copy(), backend) == pytest.approx(Polygon(A).area, rel=1e-9)


@pytest.mark.parametrize("backend", BACKENDS)
@settings(max_examples=60, deadline=None)
@given(convex_polygons(), st.floats(0.05, 0.95), st.floats(0.0, 2 * np.pi))
def test_overlap_with_contained_polygon_is_its_area(backend, A, ratio, angle):
    P = Polygon(A)
    # a copy scaled about the centroid lies inside A; it may also be rotated when it fits
    # in the circle inscribed about the centroid
    inner = P.scaled(ratio)
    d = A - P.centroid[:, None]
    e = np.roll(A, -1, axis=1) - A
    inradius = np.min(np.abs(e[0] * d[1] - e[1] * d[0]) / np.hypot(*e))
    if ratio * P.bounding_radius < inradius:
        inner = inner.rotated(angle)
    B = inner.vertices
    expected = inner.area
    assert overlap_area(A, B, backend) == pytest.approx(expected, rel=1e-9)
    assert overlap_area(B, A, backend) == pytest.approx(expected, rel=1e-9)


# ================================================================ scene parser
def _regular_area(n, r):
    return 0.5 * n * r * r * math.sin(2 * math.pi / n)


floats = st.floats  # shorthand


@st.composite
def valid_scenes(draw):
    """A random valid scene in the TOML layout (nested dict), with its particles' radii."""
    x0, y0 = draw(floats(-1e-2, 1e-2)), draw(floats(-1e-2, 1e-2))
    w, h = draw(floats(2e-3, 2e-2)), draw(floats(2e-3, 2e-2))
    box = [x0, y0, x0 + w, y0 + h]
    assume(box[2] > box[0] and box[3] > box[1])
    particles = []
    for _ in range(draw(st.integers(1, 3))):
        r = draw(floats(0.05, 0.2)) * min(w, h)
        p = {
            "sides": draw(st.integers(3, 40)),
            "radius": r,
            "center": [
                box[0] + 1.01 * r + draw(floats(0, 1)) * (w - 2.02 * r),
                box[1] + 1.01 * r + draw(floats(0, 1)) * (h - 2.02 * r),
            ],
            "density": draw(floats(1.0, 1e4)),
        }
        for key, strat in (
            ("angle", floats(-10.0, 10.0)),
            ("velocity", st.lists(floats(-1.0, 1.0), min_size=2, max_size=2)),
            ("angular_velocity", floats(-10.0, 10.0)),
            ("core_ratio", floats(0.01, 1.0)),
        ):
            if draw(st.booleans()):
                p[key] = draw(strat)
        particles.append(p)
    data = {"domain": {"box": box}, "particles": particles}
    if draw(st.booleans()):
        data["domain"]["wall_thickness"] = draw(floats(1e-5, 1e-2))
    if draw(st.booleans()):
        data["fluid"] = {"density": draw(floats(1.0, 1e4)), "viscosity": draw(floats(1e-6, 1.0))}
    if draw(st.booleans()):
        data["gravity"] = [draw(floats(-20.0, 20.0)), draw(floats(-20.0, 20.0))]
    contacts = {}
    for key, strat in (("E", floats(1e3, 1e10)), ("mu", floats(0, 1)), ("gamma", floats(0, 1))):
        if draw(st.booleans()):
            contacts[key] = draw(strat)
    if contacts:
        data["contacts"] = contacts
    t_end = draw(floats(1e-6, 10.0))
    data["time"] = {"t_end": t_end, "dt": t_end * draw(floats(1e-4, 1.0))}
    if draw(st.booleans()):  # a DEM step below the stable one
        mass = np.array([p["density"] * _regular_area(p["sides"], p["radius"]) for p in particles])
        bound = stable_time_step(mass, contacts.get("E", 1e7), contacts.get("gamma", 0.1))
        data["time"]["dem_dt"] = bound * draw(floats(0.01, 0.99))
    mesh = {"kind": draw(st.sampled_from(["graded", "uniform", "group"]))}
    for key, strat in (("delta_l", floats(1e-6, 1e-2)), ("sigma", floats(1.01, 1.6)),
                       ("h", floats(1e-6, 1e-2))):
        if draw(st.booleans()):
            mesh[key] = draw(strat)
    data["mesh"] = mesh
    effects = {}
    for key in ("fluid", "gravity", "convection", "rotation", "remeshing"):
        if draw(st.booleans()):
            effects[key] = draw(st.booleans())
    if draw(st.booleans()):
        effects["contacts"] = draw(st.sampled_from([True, False, "auto"]))
    data["effects"] = effects
    data["coupling"] = {"scheme": draw(st.sampled_from(["monolithic", "partitioned"]))}
    if draw(st.booleans()):
        data["coupling"]["remesh_fraction"] = draw(floats(0.01, 1.0))
    out = {"vtu_every": draw(st.integers(0, 1000))}
    if draw(st.booleans()):
        out["directory"] = draw(st.sampled_from(["out/x", "results", "/tmp/skfem-granular-out"]))
    data["output"] = out
    return data


def check_scene_keeps_values(sc: Scene, data: dict) -> None:
    assert sc.domain == tuple(data["domain"]["box"])
    assert sc.wall_thickness == data["domain"].get("wall_thickness", 0.5e-3)
    assert len(sc.particles) == len(data["particles"])
    for ps, p in zip(sc.particles, data["particles"], strict=True):
        assert ps.density == p["density"]
        assert ps.velocity == tuple(p.get("velocity", (0.0, 0.0)))
        assert ps.angular_velocity == p.get("angular_velocity", 0.0)
        assert ps.core_ratio == p.get("core_ratio", 1.0)
        poly = ps.polygon
        assert poly.n == p["sides"]
        r = p["radius"]
        assert poly.area == pytest.approx(_regular_area(p["sides"], r), rel=1e-9)
        np.testing.assert_allclose(poly.centroid, p["center"], rtol=0, atol=1e-9 * r)
        np.testing.assert_allclose(poly.bounding_radius, r, rtol=1e-9)
        ang = p.get("angle", 0.0)
        first = np.array(p["center"]) + r * np.array([math.cos(ang), math.sin(ang)])
        np.testing.assert_allclose(poly.vertices[:, 0], first, rtol=0, atol=1e-9 * r)
    if "fluid" in data:
        assert (sc.fluid.density, sc.fluid.viscosity) == (
            data["fluid"]["density"],
            data["fluid"]["viscosity"],
        )
    else:
        assert sc.fluid is None and sc.dry
    assert sc.gravity == tuple(data.get("gravity", (0.0, -9.81)))
    c = data.get("contacts", {})
    law = sc.contact_law
    assert (law.E, law.mu, law.gamma) == (c.get("E", 1e7), c.get("mu", 0.3), c.get("gamma", 0.1))
    t = data["time"]
    assert (sc.time.t_end, sc.time.dt, sc.time.dem_dt) == (t["t_end"], t["dt"], t.get("dem_dt"))
    m = data["mesh"]
    assert (sc.mesh.kind, sc.mesh.delta_l, sc.mesh.sigma, sc.mesh.h) == (
        m["kind"],
        m.get("delta_l"),
        m.get("sigma"),
        m.get("h"),
    )
    e = data["effects"]
    for key in ("gravity", "convection", "rotation", "remeshing"):
        assert getattr(sc.effects, key) == e.get(key, True)
    assert sc.effects.contacts == e.get("contacts", "auto")
    assert sc.effects.fluid == (e.get("fluid", True) and "fluid" in data)
    assert sc.coupling == data["coupling"]["scheme"]
    assert sc.remesh_fraction == data["coupling"].get("remesh_fraction", 0.25)
    assert sc.vtu_every == data["output"]["vtu_every"]
    assert sc.output_dir == data["output"].get("directory")


def to_toml(data: dict) -> str:
    """The TOML text of a scene dictionary (the subset of TOML the layout uses)."""

    def value(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, (int, float)):
            return repr(v)
        if isinstance(v, str):
            return json.dumps(v)
        return "[" + ", ".join(value(x) for x in v) + "]"

    def table(d):
        return "".join(f"{k} = {value(v)}\n" for k, v in d.items())

    text = "".join(f"{k} = {value(v)}\n" for k, v in data.items() if not isinstance(v, (dict, list))
                   or (isinstance(v, list) and not isinstance(v[0], dict)))
    for k, v in data.items():
        if isinstance(v, dict):
            text += f"\n[{k}]\n" + table(v)
        elif isinstance(v, list) and isinstance(v[0], dict):
            text += "".join(f"\n[[{k}]]\n" + table(x) for x in v)
    return text


@settings(max_examples=60, deadline=None)
@given(valid_scenes())
def test_valid_scenes_round_trip_through_from_dict(data):
    snapshot = json.dumps(data)
    sc = Scene.from_dict(data, name="random")
    assert json.dumps(data) == snapshot  # the input is not modified
    assert sc.name == "random"
    check_scene_keeps_values(sc, data)


@settings(max_examples=30, deadline=None)
@given(valid_scenes())
def test_valid_scenes_round_trip_through_toml(data):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "random.toml"
        path.write_text(to_toml(data))
        sc = Scene.from_toml(path)
    assert sc.name == "random"
    check_scene_keeps_values(sc, data)


# field path -> (lower bound, lower bound allowed?, upper bound or None, optional?)
NUMERIC = {
    ("domain", "wall_thickness"): (0.0, False, None, False),
    ("fluid", "density"): (0.0, False, None, False),
    ("fluid", "viscosity"): (0.0, False, None, False),
    ("contacts", "E"): (0.0, False, None, False),
    ("contacts", "mu"): (0.0, True, None, False),
    ("contacts", "gamma"): (0.0, True, None, False),
    ("time", "t_end"): (0.0, False, None, False),
    ("time", "dt"): (0.0, False, None, False),
    ("time", "dem_dt"): (0.0, False, None, True),
    ("mesh", "delta_l"): (0.0, False, None, True),
    ("mesh", "h"): (0.0, False, None, True),
    ("mesh", "sigma"): (1.0, False, 1.6, True),
    ("coupling", "remesh_fraction"): (0.0, False, 1.0, False),
    ("particles[0]", "density"): (0.0, False, None, False),
    ("particles[0]", "radius"): (0.0, False, None, False),
    ("particles[0]", "core_ratio"): (0.0, False, 1.0, False),
    ("particles[0]", "angle"): (None, False, None, False),
    ("particles[0]", "angular_velocity"): (None, False, None, False),
}
FIELDS = sorted(NUMERIC)


@st.composite
def invalid_values(draw, field):
    lo, lo_closed, hi, optional = NUMERIC[field]
    options = [
        st.sampled_from([math.nan, math.inf, -math.inf]),
        st.booleans(),
        st.sampled_from(["abc", "", "1e-3 m", "fast"]),
        st.lists(floats(0.1, 1.0), min_size=1, max_size=2),
    ]
    if not optional:
        options.append(st.none())
    if lo is not None:
        options.append(floats(max_value=lo, exclude_max=lo_closed, allow_nan=False))
    if hi is not None:
        options.append(floats(min_value=hi, exclude_min=True, allow_nan=False))
    return draw(st.one_of(options))


def _base_scene() -> dict:
    return {
        "domain": {"box": [0.0, 0.0, 3e-3, 11e-3], "wall_thickness": 0.5e-3},
        "fluid": {"density": 1000.0, "viscosity": 1e-3},
        "particles": [{"sides": 24, "radius": 0.5e-3, "center": [1.5e-3, 5.5e-3],
                       "density": 2650.0, "angle": 0.0, "angular_velocity": 0.0,
                       "core_ratio": 1.0}],
        "contacts": {"E": 1e7, "mu": 0.3, "gamma": 0.1},
        "time": {"t_end": 1e-3, "dt": 1e-5},
        "mesh": {"kind": "graded"},
        "coupling": {"scheme": "monolithic", "remesh_fraction": 0.25},
    }


@settings(max_examples=150, deadline=None)
@given(st.data())
def test_invalid_numbers_name_the_field(data):
    field = data.draw(st.sampled_from(FIELDS), label="field")
    bad = data.draw(invalid_values(field), label="value")
    d = _base_scene()
    section, key = field
    target = d["particles"][0] if section == "particles[0]" else d[section]
    target[key] = bad
    with pytest.raises(ValueError) as info:
        Scene.from_dict(d)
    msg = str(info.value)
    assert f"{section}.{key}" in msg, msg
    assert "\n" not in msg
