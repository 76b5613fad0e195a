"""`skfem-granular render`: a PNG of a run's last frame from the command line.

Bad options and output paths are refused with exit status 2 and one line before any
rendering; a write that fails midway exits with status 1 and leaves the earlier file.
"""

from dataclasses import replace

import numpy as np
import pytest
from helpers import only_error_line

from skfem_granular.cli import main
from skfem_granular.scene import bundled

SCENE = bundled("single_particle")


def test_render_png_of_last_frame(tmp_path, capsys):
    pytest.importorskip("pyvista", reason="pyvista is the 'plot' extra")
    out = tmp_path / "run"
    assert main(["run", str(SCENE), "--out", str(out), "--t-end", "3e-5", "--no-progress"]) == 0
    png = tmp_path / "last.png"
    assert main(["render", str(out), "--png", str(png), "--field", "pressure"]) == 0
    from PIL import Image

    img = np.asarray(Image.open(png).convert("RGB"), dtype=float)
    assert img.shape[0] > 100 and img.shape[1] > 50
    assert img.std() > 20  # not blank: a colour field, a colour bar and the particle


def test_render_bad_directory_exit_code(tmp_path, capsys):
    assert main(["render", str(tmp_path / "nothing"), "--png", "x.png"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no flow.pvd" in err[0]


def test_render_animation_every_other_frame(tmp_path, capsys):
    pytest.importorskip("pyvista", reason="pyvista is the 'plot' extra")
    out = tmp_path / "run"
    # 4 steps with a frame every step: frames at steps 0..4 (5), every 2nd -> 3
    assert main(["run", str(SCENE), "--out", str(out), "--t-end", "4e-5", "--dt", "1e-5",
                 "--vtu-every", "1", "--no-progress"]) == 0
    from skfem_granular.io import read_pvd

    n = len(read_pvd(out / "flow.pvd"))
    gif = tmp_path / "run.gif"
    assert main(["render", str(out), "--animation", str(gif), "--every", "2",
                 "--fps", "4"]) == 0
    from PIL import Image

    with Image.open(gif) as im:
        assert im.n_frames == (n + 1) // 2
        assert im.info["duration"] == 250  # ms per frame at 4 fps
    capsys.readouterr()
    assert main(["render", str(out), "--animation", str(gif), "--every", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "every = 0" in err[0]


# ---------------------------------------------------------------- refusals and failed writes
@pytest.fixture(scope="module")
def run_out(tmp_path_factory):
    """A run of 4 steps with a frame every 2nd (3 frames)."""
    from skfem_granular.scene import Scene
    from skfem_granular.simulation import Simulation

    sc = Scene.bundled("single_particle")
    sc = replace(sc, time=replace(sc.time, t_end=4e-5, dt=1e-5), vtu_every=2, output_dir=None)
    out = tmp_path_factory.mktemp("run")
    Simulation(sc, output_dir=out).run(progress=False)
    return out


@pytest.fixture
def no_rendering(monkeypatch):
    """Rendering fails the test: a refusal must come before it."""
    from skfem_granular import viz

    def fail(*a, **k):
        raise AssertionError("rendering started")

    monkeypatch.setattr(viz, "render_frame", fail)
    monkeypatch.setattr(viz, "render_series", fail)


@pytest.mark.parametrize("fps", ["1e-300", "0", "0.05", "100.5", "1e300", "inf", "nan", "-4"])
def test_fps_out_of_range_exit_2_and_the_gif_unchanged(run_out, tmp_path, capsys, fps,
                                                       no_rendering):
    gif = tmp_path / "run.gif"
    gif.write_bytes(b"GIF89a the earlier animation")
    assert main(["render", str(run_out), "--animation", str(gif), "--fps", fps]) == 2
    assert only_error_line(capsys) == (f"skfem-granular: error: --fps = {float(fps)!r}: must be a "
                                  "finite number in [0.1, 100]")
    assert gif.read_bytes() == b"GIF89a the earlier animation"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.gif"]


def test_fps_at_the_ends_of_the_range(run_out, tmp_path, capsys):
    """0.1 and 100 fps: frames of 10 s and of 10 ms (one hundredth, the GIF's unit)."""
    pytest.importorskip("pyvista", reason="pyvista is the 'plot' extra")
    from PIL import Image

    for fps, ms in (("0.1", 10000), ("100", 10)):
        gif = tmp_path / f"fps{fps}.gif"
        assert main(["render", str(run_out), "--animation", str(gif), "--fps", fps,
                     "--every", "2"]) == 0
        with Image.open(gif) as im:
            assert (im.n_frames, im.info["duration"]) == (2, ms)
    capsys.readouterr()


@pytest.mark.parametrize("every", ["0", "-3"])
def test_every_below_one_exit_2(run_out, tmp_path, capsys, every, no_rendering):
    assert main(["render", str(run_out), "--animation", str(tmp_path / "a.gif"),
                 "--every", every]) == 2
    assert only_error_line(capsys) == (f"skfem-granular: error: --every = {int(every)}: must be an "
                                  "integer >= 1")


def test_png_under_a_file_exit_2_before_rendering(run_out, tmp_path, capsys, no_rendering):
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    for png in (blocker / "pic.png", blocker / "sub" / "pic.png"):
        assert main(["render", str(run_out), "--png", str(png)]) == 2
        assert only_error_line(capsys) == (
            f"skfem-granular: error: --png = {str(png)!r}: must be a file that can be "
            f"written; output path {str(png)!r}: {str(blocker)!r} is not a directory")
    folder = tmp_path / "d.png"
    folder.mkdir()
    assert main(["render", str(run_out), "--png", str(folder)]) == 2
    assert only_error_line(capsys).endswith(f"output path {str(folder)!r}: is a directory")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file", "d.png"]


def test_unwritable_folder_exit_2_before_rendering(run_out, tmp_path, capsys, monkeypatch,
                                                   no_rendering):
    """A folder the user may not write to (made so for the check: the tests may run as
    root, who may write anywhere)."""
    import os

    from skfem_granular.io import files

    locked = tmp_path / "locked"
    locked.mkdir()
    real = os.access
    monkeypatch.setattr(files.os, "access",
                        lambda p, mode: False if str(p) == str(locked) else real(p, mode))
    for option, name in (("--png", "pic.png"), ("--animation", "run.gif")):
        assert main(["render", str(run_out), option, str(locked / name)]) == 2
        assert only_error_line(capsys).endswith(f"directory {str(locked)!r} is not writable")
    assert not list(locked.iterdir())


def test_bad_animation_path_refused_before_the_png(run_out, tmp_path, capsys, no_rendering):
    png = tmp_path / "pic.png"
    assert main(["render", str(run_out), "--png", str(png), "--animation",
                 str(tmp_path / "run.avi")]) == 2
    assert only_error_line(capsys).endswith(f"--animation = {str(tmp_path / 'run.avi')!r}: must "
                                       "end in .gif or .mp4")
    assert not png.exists()


def test_failed_write_exit_1_and_the_earlier_png_kept(run_out, tmp_path, capsys, monkeypatch):
    """Pillow fails midway (partial bytes, then a full disk): exit status 1, one line, the
    earlier PNG byte for byte, no temporary file."""
    pytest.importorskip("pyvista", reason="pyvista is the 'plot' extra")
    import errno
    import os

    from PIL import Image

    png = tmp_path / "pic.png"
    assert main(["render", str(run_out), "--png", str(png)]) == 0
    before = png.read_bytes()

    def save(self, fp, *args, **kwargs):
        with open(fp, "wb") as fh:
            fh.write(b"\x89PNG half")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(Image.Image, "save", save)
    capsys.readouterr()
    assert main(["render", str(run_out), "--png", str(png), "--field", "pressure"]) == 1
    assert only_error_line(capsys) == ("skfem-granular: error: render: No space left on device "
                                  "(a file written before keeps its content)")
    assert png.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pic.png"]
