"""The scenes shipped with the package: found by name, parsed, run from the command line."""

import json
from pathlib import Path

import pytest

import skfem_granular
from skfem_granular.cli import main
from skfem_granular.scene import Scene, bundled, bundled_scenes

NAMES = ("collapse", "single_particle", "single_particle_fine")
PACKAGE = Path(skfem_granular.__file__).resolve().parent


def test_bundled_scenes_are_the_three_paper_runs():
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
    assert len(col.particles) == 25 and col.mesh.kind == "group"
    assert col.time.t_end == 0.16 and col.time.dt == 2e-4 and col.contact_law.E == 1e7


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
    assert "on the graded mesh" in lines[1] and "equidistant (fine) mesh" in lines[2]
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
