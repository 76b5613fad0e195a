"""Bad input gives a ValueError naming the parameter and the allowed range."""

import numpy as np
import pytest

import meshing

BOX = (0.0, 0.0, 3e-3, 11e-3)


def regular(n, r=0.5e-3, c=(1.5e-3, 5.5e-3), rot=0.0):
    th = rot + 2.0 * np.pi * np.arange(n) / n
    return np.vstack([c[0] + r * np.cos(th), c[1] + r * np.sin(th)])


DISK = regular(24)
NONCONVEX = np.array([[0, 2, 2, 1, 0], [0, 0, 2, 0.5, 2]], dtype=float) * 1e-4 + np.array(
    [[1e-3], [5e-3]])
STAR = regular(5)[:, [0, 2, 4, 1, 3]]          # pentagram: left turns only, winds twice


class Particle:
    vertices = DISK


BAD = {
    "clockwise": (dict(particles=[DISK[:, ::-1]]), r"particles\[0\]: outline is clockwise"),
    "non-convex": (dict(particles=[NONCONVEX]),
                   r"particles\[0\]: outline is not convex \(vertex 3 turns clockwise\)"),
    "self-intersecting": (dict(particles=[STAR]), r"particles\[0\]: outline is self-inter"),
    "overlap": (dict(particles=[DISK, regular(24, c=(1.5e-3, 6.2e-3))]),
                r"particles\[0\] and particles\[1\] overlap"),
    "outside": (dict(particles=[regular(24, c=(0.3e-3, 5e-3))]),
                r"particles\[0\]: vertex \d+ at .* is not strictly inside the domain"),
    "delta_l too large": (dict(particles=[DISK], delta_l=0.6e-3),
                          r"delta_l: must be <= 0.0005 \(circumradius of the smallest"),
    "delta_l negative": (dict(particles=[DISK], delta_l=-1.0), r"delta_l: must be > 0"),
    "sigma 1": (dict(particles=[DISK], sigma=1.0),
                r"sigma: growth factor must be in \(1, 1.6\], got 1.0"),
    "sigma too large": (dict(particles=[DISK], sigma=1.7),
                        r"sigma: growth factor must be in \(1, 1.6\], got 1.7"),
    "coarse outline": (dict(particles=[regular(6)]),
                       r"particles\[0\]: outline edges .* pass delta_l <= "),
    "domain order": (dict(domain=(0.0, 0.0, -1.0, 1.0), particles=[DISK]),
                     r"domain: need x0 < x1 and y0 < y1"),
    "domain text": (dict(domain=("a", 0, 1, 1), particles=[DISK]),
                    r"domain: expected \(x0, y0, x1, y1\)"),
    "domain shape": (dict(domain=np.zeros((3, 4)), particles=[DISK]),
                     r"domain: expected a \(2, N\) array"),
    "domain nan": (dict(domain=(0.0, 0.0, np.nan, 1.0), particles=[DISK]),
                   r"domain: \(x0, y0, x1, y1\) must be finite"),
    "single array": (dict(particles=DISK), r"particles: expected a list .* wrap it in a list"),
    "two vertices": (dict(particles=[np.zeros((2, 2))]), r"particles\[0\]: .*N >= 3"),
    "nan vertex": (dict(particles=[np.where(np.arange(24) == 3, np.nan, DISK)]),
                   r"particles\[0\]: vertices must be finite"),
    "repeated vertex": (dict(particles=[DISK[:, [0, 1, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12]]]),
                        r"particles\[0\]: vertices 1 and 2 coincide"),
    "no particles": (dict(particles=[]), r"particles: graded_mesh needs at least one"),
    "sigma text": (dict(particles=[DISK], sigma="big"), r"sigma: expected a number"),
    "relax rounds": (dict(particles=[DISK], relax_rounds=-1),
                     r"relax_rounds: must be an integer in \[0, 20\]"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_graded_bad_input(case):
    kw, msg = BAD[case]
    kw = {"domain": BOX, **kw}
    with pytest.raises(ValueError, match=msg):
        meshing.graded_mesh(**kw)


def test_objects_with_vertices_are_accepted():
    mesh = meshing.graded_mesh(BOX, [Particle()])
    assert mesh.boundaries["particle0"].size == 24


@pytest.mark.parametrize("h, msg", [(0.0, r"h: must be in \(0, 0.0015\]"),
                                    (2e-3, r"h: must be in \(0, 0.0015\]"),
                                    ("x", r"h: expected a number")])
def test_uniform_bad_h(h, msg):
    with pytest.raises(ValueError, match=msg):
        meshing.uniform_mesh(BOX, [DISK], h=h)


def test_uniform_needs_h_without_particles():
    with pytest.raises(ValueError, match=r"h: required when there are no particles"):
        meshing.uniform_mesh(BOX, [])


def test_group_bad_radius_and_center():
    with pytest.raises(ValueError, match=r"radius: must be >= 0.000630"):
        meshing.group_mesh(BOX, [DISK], radius=0.55e-3)
    with pytest.raises(ValueError, match=r"center: must lie inside the domain"):
        meshing.group_mesh(BOX, [DISK], center=(-1e-3, 5e-3))


def test_remesh_bad_input():
    mesh = meshing.build("graded", BOX, [DISK])
    with pytest.raises(ValueError, match=r"particles: expected 1 outlines"):
        meshing.remesh(mesh, [DISK, regular(12, 0.2e-3, (1.5e-3, 2e-3))])
    with pytest.raises(ValueError, match=r"particles\[0\]: expected 24 vertices"):
        meshing.move_particles(mesh, [regular(12)])
    with pytest.raises(ValueError, match=r"mesh: has no meshing_recipe"):
        import skfem
        meshing.remesh(skfem.MeshTri(), [DISK])
    with pytest.raises(ValueError, match=r"min_angle: must be in \(0, 60\)"):
        meshing.remesh_needed(mesh, min_angle=70.0)
    with pytest.raises(ValueError, match=r"max_aspect: must be > 1"):
        meshing.remesh_needed(mesh, max_aspect=0.5)


def test_build_and_value_bad_input():
    with pytest.raises(ValueError, match=r"kind: expected one of 'graded', 'uniform', 'group'"):
        meshing.build("fine", BOX, [DISK])
    with pytest.raises(TypeError, match=r"options: 'h' not accepted by kind 'graded'"):
        meshing.build("graded", BOX, [DISK], h=1e-4)
    plain = meshing.graded_mesh(BOX, [DISK])
    with pytest.raises(ValueError, match=r"mesh: has no meshing_recipe \(got a bare skfem"):
        meshing.move_particles(plain, [DISK])
    unknown = meshing.BodyFittedMesh(plain, None, ())
    with pytest.raises(ValueError, match=r"mesh: has no meshing_recipe \(got a BodyFitted"):
        meshing.remesh(unknown, [DISK])
