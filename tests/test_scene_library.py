"""The scenes shipped with the package: found by name, parsed, run from the command line."""

import json
from pathlib import Path

import numpy as np
import pytest

import skfem_granular
from skfem_granular.cli import main
from skfem_granular.scene import Scene, bundled, bundled_scenes

PAPER = ("collapse", "collapse_group", "single_particle", "single_particle_fine")
#: the sedimentation and repose checks (docs/sedimentation.md)
SEDIMENTATION = ("dkt_two_disks", "dkt_uhlmann", "migration_off_centre", "repose_hexagons",
                 "settling_disk_channel", "settling_disk_k3", "settling_disk_k8_tall",
                 "settling_disk_re350", "settling_hexagon", "settling_rectangle")
NAMES = tuple(sorted(PAPER + SEDIMENTATION))
PACKAGE = Path(skfem_granular.__file__).resolve().parent


def test_bundled_scenes_are_the_paper_runs_and_the_sedimentation_checks():
    scenes = bundled_scenes()
    assert tuple(scenes) == NAMES
    for name, path in scenes.items():
        assert path.is_file() and path.name == f"{name}.toml"
        assert path.resolve().is_relative_to(PACKAGE)


@pytest.mark.parametrize("name", NAMES)
def test_every_bundled_scene_parses(name):
    scene = Scene.from_toml(bundled(name))
    assert scene.name == name
    again = Scene.bundled(name)
    assert again.name == name and again.time == scene.time and again.mesh == scene.mesh
    assert len(again.particles) == len(scene.particles)


def test_bundled_scenes_keep_the_paper_numbers():
    sp, fine, col = (Scene.bundled(n) for n in ("single_particle", "single_particle_fine",
                                                "collapse"))
    for sc, kind in ((sp, "graded"), (fine, "uniform")):
        assert sc.mesh.kind == kind and sc.time.t_end == 1e-3 and sc.time.dt == 1e-5
        assert len(sc.particles) == 1 and sc.particles[0].polygon.vertices.shape == (2, 24)
        assert sc.domain == (0.0, 0.0, 3e-3, 11e-3)
    assert sp.output_dir == "out/single_particle"
    assert len(col.particles) == 25 and col.mesh.kind == "auto" and col.mesh.delta_l == 2e-4
    assert col.time.t_end == 0.16 and col.time.dt == 2e-4 and col.contact_law.E == 1e7
    # the paper's Fig. 13 mesh: the same scene on the group construction
    grp = Scene.bundled("collapse_group")
    assert grp.mesh.kind == "group" and grp.output_dir == "out/collapse_group"
    assert (grp.domain, grp.time, grp.contact_law, grp.mesh.delta_l) == (
        col.domain, col.time, col.contact_law, col.mesh.delta_l)
    for a, b in zip(grp.particles, col.particles, strict=True):
        np.testing.assert_array_equal(a.polygon.vertices, b.polygon.vertices)


@pytest.mark.parametrize("name", ["collapse", "collapse_group"])
def test_collapse_steps_coarse_at_contacts_on_purpose_without_a_warning(name):
    """The collapse's 0.2 ms steps are ~50 DEM stable steps: the scene says so
    (time.contact_warning = false) and is not warned about; the same scene without
    that line is."""
    from dataclasses import replace

    from skfem_granular.dem import DEMSystem
    from skfem_granular.simulation.effects import scene_warnings

    sc = Scene.bundled(name)
    assert sc.effects.contacts is True and not sc.time.adaptive and not sc.time.contact_warning
    dem = DEMSystem.in_box([p.to_dem() for p in sc.particles], sc.domain, sc.wall_thickness,
                           law=sc.contact_law)
    assert sc.time.dt > 40 * dem.dt_stable
    assert scene_warnings(sc, dem, True) == []
    user = replace(sc, time=replace(sc.time, contact_warning=True))
    (w,) = scene_warnings(user, dem, True)
    assert w.startswith("time.dt = 0.0002 s does not resolve a contact")


@pytest.mark.parametrize("spelling", ["single-particle", "single_particle", "single_particle.toml",
                                      "single-particle.toml"])
def test_bundled_names_hyphens_underscores_suffix(spelling):
    path = bundled(spelling)
    assert path == bundled("single_particle")
    assert path.resolve().is_relative_to(PACKAGE)
    assert bundled("single-particle-fine") == bundled("single_particle_fine.toml")


@pytest.mark.parametrize("name", ["no-such-scene", "scenes/single_particle.toml", "", 3])
def test_unknown_name_lists_the_bundled_scenes(name):
    with pytest.raises(ValueError) as exc:
        bundled(name)
    msg = str(exc.value)
    assert "\n" not in msg and "no bundled scene" in msg
    assert all(n in msg for n in NAMES)
    with pytest.raises(ValueError, match="single_particle_fine"):
        Scene.bundled("nope")


def test_cli_scenes_lists_names_and_first_comment(capsys):
    assert main(["scenes"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert [ln.split()[0] for ln in lines] == list(NAMES)
    by_name = {ln.split()[0]: ln for ln in lines}
    assert "on the graded mesh" in by_name["single_particle"]
    assert "equidistant (fine) mesh" in by_name["single_particle_fine"]
    assert all("#" not in ln for ln in lines)


def test_cli_runs_bundled_scene_by_name(tmp_path, monkeypatch, capsys):
    """``run single-particle`` writes to the scene's output directory, relative to the cwd."""
    monkeypatch.chdir(tmp_path)
    assert main(["run", "single-particle", "--t-end", "2e-5", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "scene: single_particle" in out and "734 P2 nodes" in out
    summary = json.loads((tmp_path / "out" / "single_particle" / "summary.json").read_text())
    assert summary["steps"] == 2


def test_cli_existing_path_wins_over_bundled_name(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    bad = "[domain]\nbox = [0, 0, 1, 1]\n[time]\ndt = -1\n"  # not the bundled scene
    (tmp_path / "single_particle.toml").write_text(bad)
    assert main(["run", "single_particle.toml"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "time.dt" in err[0]


def test_cli_unknown_scene_is_a_missing_file(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["run", "no-such-scene"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "scene file 'no-such-scene': not found" in err[0]


def test_sedimentation_scenes_keep_the_published_set_ups():
    """cgs set-ups of the sedimentation checks converted to SI (docs/sedimentation.md)."""
    sc = {n: Scene.bundled(n) for n in SEDIMENTATION}
    g = sc["settling_disk_channel"]
    assert g.domain == (0.0, 0.0, 0.02, 0.06) and g.fluid.viscosity == 0.01
    (p,) = g.particles
    core = p.polygon.vertices
    r_core = np.hypot(*(p.polygon.vertices - p.polygon.centroid[:, None])).max() * p.core_ratio
    assert core.shape == (2, 32) and r_core == pytest.approx(1.25e-3, rel=1e-12)
    assert np.allclose(p.polygon.centroid, (0.01, 0.04))
    # mass and immersed weight of the published disk: density x shadow area = 1250 x core area
    assert p.density * p.polygon.area == pytest.approx(1250.0 * p.polygon.area * 0.95**2)
    d = sc["dkt_two_disks"]
    assert d.domain == (0.0, 0.0, 0.02, 0.08) and d.fluid.viscosity == 1e-3
    assert [tuple(np.round(q.polygon.centroid, 6)) for q in d.particles] == [(0.01, 0.068),
                                                                          (0.00999, 0.072)]
    assert all(q.density / q.core_ratio**2 == pytest.approx(1010.0) for q in d.particles)
    tall = sc["settling_disk_k8_tall"]
    assert tall.domain == (0.0, 0.0, 0.02, 0.16) and tall.particles[0].density == p.density
    assert tall.particles[0].polygon.vertices.shape == (2, 32) and tall.mesh == g.mesh
    k3 = sc["settling_disk_k3"]
    assert k3.domain[2] == 3e-3 and k3.particles[0].polygon.vertices.shape == (2, 24)
    rep = sc["repose_hexagons"]
    assert rep.dry and len(rep.particles) >= 200 and rep.contact_law.mu == 0.4
    assert all(q.polygon.vertices.shape == (2, 6) for q in rep.particles)
    rect = sc["settling_rectangle"].particles[0].polygon
    e = np.linalg.norm(np.diff(rect.vertices, axis=1, append=rect.vertices[:, :1]), axis=0)
    assert e.max() / e.min() == pytest.approx(2.0)
