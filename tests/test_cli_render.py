"""`skfem-granular render`: a PNG of a run's last frame from the command line."""

import numpy as np
import pytest

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
