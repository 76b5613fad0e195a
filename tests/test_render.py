"""Off-screen pictures of a run (skfem_granular.viz): PNG frames and a GIF.

One tiny run of the bundled single_particle.toml (3 steps, frames at 0, 2e-5 and
3e-5 s) feeds all tests. The checks are on pixels: size, contrast, the
colour map's high end next to the particle, its low end far from it, the
white background, the black core outline along the particle's polygon and
the grey fill inside it.
"""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from skfem_granular import viz

ROOT = Path(__file__).resolve().parents[1]


def _pyvista_missing() -> str | None:
    try:
        viz.require_pyvista()
    except ImportError as exc:
        return str(exc)
    except RuntimeError:
        return None  # no GL libraries: the tests run and fail with that message
    return None


MISSING = _pyvista_missing()
needs_pyvista = pytest.mark.skipif(MISSING is not None, reason=f"pyvista: {MISSING}")


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    from skfem_granular.scene import Scene
    from skfem_granular.simulation import Simulation

    scene = Scene.bundled("single_particle")
    scene = replace(scene, time=replace(scene.time, t_end=3e-5), vtu_every=2)
    out = tmp_path_factory.mktemp("run")
    Simulation(scene, output_dir=out).run(progress=False)
    return out


def _core(particles_vtu):
    """Vertices and edge midpoints of the particle core outline."""
    import pyvista as pv

    p = pv.read(particles_vtu)
    core = p.extract_cells(np.flatnonzero(np.asarray(p.cell_data["kind"]) == 1))
    V = np.asarray(core.points)[:, :2]
    return V, np.vstack([V, (V + np.roll(V, 1, axis=0)) / 2])


def _near(image, rc, colour, tol, reach=2) -> bool:
    """Is a pixel within ``reach`` of ``rc`` within ``tol`` (max norm) of ``colour``?"""
    r, c = rc
    patch = image[max(r - reach, 0) : r + reach + 1, max(c - reach, 0) : c + reach + 1]
    return bool(np.any(np.max(np.abs(patch.astype(int) - colour), axis=-1) <= tol))


@needs_pyvista
def test_speed_png(run_dir, tmp_path):
    from matplotlib import colormaps
    from PIL import Image

    flow, parts = run_dir / "flow_00002.vtu", run_dir / "particles_00002.vtu"
    pic = viz.render_frame(
        flow, parts, tmp_path / "speed.png", field="speed", window_size=(400, 800), time=3e-5
    )
    with Image.open(tmp_path / "speed.png") as png:
        assert png.size == (400, 800)
        image = np.asarray(png.convert("RGB"))
    assert pic.image.shape == (800, 400, 3)
    np.testing.assert_array_equal(image, pic.image)
    assert image.astype(float).std() > 20  # not blank
    assert pic.clim[0] == 0 and 1e-5 < pic.clim[1] < 1e-3  # m/s after 3 steps
    high = np.array(colormaps["viridis"](1.0)[:3]) * 255
    low = np.array(colormaps["viridis"](0.0)[:3]) * 255

    V, outline = _core(parts)
    center = V.mean(axis=0)
    # the black core outline along the whole polygon, grey inside
    assert all(_near(image, pic.pixel(*x), viz.CORE_EDGE, 60) for x in outline)
    assert _near(image, pic.pixel(*center), (200, 200, 200), 10, reach=0)
    # the colour map's high end within 0.1 mm of the particle (at its sides)
    ring = [
        pic.pixel(*(center + r * np.array([np.cos(a), np.sin(a)])))
        for r in np.linspace(0.52e-3, 0.6e-3, 5)
        for a in np.linspace(0, 2 * np.pi, 72, endpoint=False)
    ]
    assert any(_near(image, rc, high, 40, reach=0) for rc in ring)
    # the low end far from it, white background outside the plot area
    assert _near(image, pic.pixel(0.3e-3, 0.5e-3), low, 20, reach=0)
    assert _near(image, pic.pixel(2.7e-3, 10.5e-3), low, 20, reach=0)
    assert (image[:4, -4:] == 255).all()
    # the walls around the box
    assert _near(image, pic.pixel(-0.03e-3, 5e-3), (140, 140, 140), 10, reach=0)


@needs_pyvista
def test_mesh_glyphs_streamlines_zoom(run_dir):
    flow, parts = run_dir / "flow_00002.vtu", run_dir / "particles_00002.vtu"
    edge = tuple(int(viz.MESH_EDGE[i : i + 2], 16) for i in (1, 3, 5))

    mesh = viz.render_frame(flow, parts, field="mesh")
    assert mesh.clim is None and mesh.path is None
    close = np.max(np.abs(mesh.image.astype(int) - edge), axis=-1) <= 40
    assert close.sum() > 1000  # the triangle edges

    box = (0.7e-3, 4.7e-3, 2.3e-3, 6.3e-3)
    dark = {}
    for vectors in (None, "glyphs", "streamlines"):
        pic = viz.render_frame(
            flow, parts, field="pressure", vectors=vectors, box=box, window_size=(450, 300)
        )
        assert pic.image.shape == (300, 450, 3) and pic.box == box
        # the zoom: the particle (1 mm across) spans about 5/8 of the plot height
        _, outline = _core(parts)
        assert all(_near(pic.image, pic.pixel(*x), viz.CORE_EDGE, 60) for x in outline)
        # black pixels in the fluid right of the particle (0.05 mm and more
        # from its outline): arrows or lines
        r0, c0 = pic.pixel(2.05e-3, 6.0e-3)
        r1, c1 = pic.pixel(box[2], 5.0e-3)
        patch = pic.image[r0:r1, c0:c1].astype(int)
        dark[vectors] = int((patch.max(axis=-1) < 60).sum())
    assert dark[None] == 0
    assert dark["glyphs"] > 20 and dark["streamlines"] > 20


@needs_pyvista
def test_gif(run_dir, tmp_path):
    from PIL import Image, ImageSequence

    path = viz.render_series(run_dir, tmp_path / "run.gif", field="vorticity")
    assert path == tmp_path / "run.gif"
    with Image.open(path) as gif:
        assert gif.n_frames == 3
        frames = [np.asarray(f.convert("RGB"), dtype=float) for f in ImageSequence.Iterator(gif)]
    assert all(f.shape == frames[0].shape for f in frames)
    assert all(f.std() > 20 for f in frames)
    # one colour range for all frames: the fluid at rest at t = 0 is the
    # colour of zero (white in RdBu_r); later frames are not
    assert np.abs(frames[2] - frames[1]).mean() > 0.1
    with Image.open(viz.render_series(run_dir, tmp_path / "two.gif", every=2)) as gif:
        assert gif.n_frames == 2


def test_bad_input(run_dir, tmp_path, monkeypatch):
    flow = run_dir / "flow_00000.vtu"
    with pytest.raises(ValueError, match="field"):
        viz.render_frame(flow, field="temperature")
    with pytest.raises(ValueError, match="vectors"):
        viz.render_frame(flow, vectors="arrows")
    with pytest.raises(ValueError, match="every"):
        viz.render_series(run_dir, tmp_path / "a.gif", every=0)
    with pytest.raises(ValueError, match=r"\.gif or \.mp4"):
        viz.render_series(run_dir, tmp_path / "a.avi")
    with pytest.raises(ValueError, match="not found"):
        viz.render_series(tmp_path, tmp_path / "a.gif")
    monkeypatch.setitem(__import__("sys").modules, "pyvista", None)
    with pytest.raises(ImportError, match=r"pip install 'skfem-granular\[plot\]'"):
        viz.render_frame(flow)


@needs_pyvista
def test_bad_files(run_dir, tmp_path):
    with pytest.raises(ValueError, match="not found"):
        viz.render_frame(tmp_path / "nothing.vtu")
    with pytest.raises(ValueError, match=r"\.png"):
        viz.render_frame(run_dir / "flow_00000.vtu", path_png=tmp_path / "a.jpg")
    with pytest.raises(ValueError, match="box"):
        viz.render_frame(run_dir / "flow_00000.vtu", box=(1, 1, 0, 2))


# ---------------------------------------------------------------- files written whole or not at all
def _failing_save(monkeypatch, targets):
    """Pillow's save writes a few bytes to its file, then fails as on a full disk."""
    import errno
    import os

    from PIL import Image

    def save(self, fp, *args, **kwargs):
        targets.append(Path(fp))
        with open(fp, "wb") as fh:
            fh.write(b"\x89PNG half a picture")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(fp))

    monkeypatch.setattr(Image.Image, "save", save)


def _writers(run_dir, path):
    small = {"window_size": (200, 300)}
    if path.suffix == ".png":
        return (lambda: viz.render_frame(run_dir / "flow_00002.vtu", None, path, **small),
                lambda: viz.render_frame(run_dir / "flow_00002.vtu", None, path,
                                         field="pressure", **small))
    return (lambda: viz.render_series(run_dir, path, every=2, **small),
            lambda: viz.render_series(run_dir, path, every=2, field="pressure", **small))


@needs_pyvista
@pytest.mark.parametrize("name", ["pic.png", "run.gif"])
def test_failed_write_keeps_the_earlier_file(run_dir, tmp_path, monkeypatch, name):
    """A PNG or GIF whose write fails midway (partial bytes, then ENOSPC) leaves the earlier
    file byte for byte and no temporary file; the failed write went to a temporary name."""
    path = tmp_path / name
    first, second = _writers(run_dir, path)
    first()
    before = path.read_bytes()
    targets = []
    _failing_save(monkeypatch, targets)
    with pytest.raises(OSError, match="No space left on device"):
        second()  # another field: a write that got through would change the bytes
    assert len(targets) == 1 and targets[0].parent == tmp_path
    assert targets[0].name.startswith(".partial-") and targets[0].suffix == path.suffix
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]
    monkeypatch.undo()
    second()
    assert path.read_bytes() != before  # the same call, not failing, replaces it


def _fake_imageio(monkeypatch, fail_at=None):
    """imageio.v2 (and imageio_ffmpeg) stand-ins whose MP4 writer writes ``frame;`` per frame
    and fails as on a full disk at frame ``fail_at``."""
    import errno
    import os
    import sys
    import types

    log = {"frames": 0, "closed": 0, "paths": [], "fps": []}

    class Writer:
        def __init__(self, path, fps, macro_block_size):
            log["paths"].append(Path(path))
            log["fps"].append(fps)
            self.fh = open(path, "wb")  # noqa: SIM115 (closed in close)

        def append_data(self, image):
            assert image.shape[0] % 2 == 0 and image.shape[1] % 2 == 0  # padded for H.264
            self.fh.write(b"frame;")
            log["frames"] += 1
            if log["frames"] == fail_at:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

        def close(self):
            self.fh.close()
            log["closed"] += 1

    v2 = types.ModuleType("imageio.v2")
    v2.get_writer = Writer
    pkg = types.ModuleType("imageio")
    pkg.v2 = v2
    for name, module in (("imageio", pkg), ("imageio.v2", v2),
                         ("imageio_ffmpeg", types.ModuleType("imageio_ffmpeg"))):
        monkeypatch.setitem(sys.modules, name, module)
    return log


@needs_pyvista
def test_failed_mp4_keeps_the_earlier_file(run_dir, tmp_path, monkeypatch):
    """The MP4 is streamed to a temporary file: the writer failing at the second frame leaves
    the earlier MP4 byte for byte, the writer closed and no temporary file."""
    path = tmp_path / "run.mp4"
    log = _fake_imageio(monkeypatch)
    viz.render_series(run_dir, path, fps=4, window_size=(201, 301))
    assert path.read_bytes() == b"frame;" * 3 and log["closed"] == 1 and log["fps"] == [4.0]
    assert log["paths"][0].parent == tmp_path and log["paths"][0].name.startswith(".partial-")
    path.write_bytes(b"the earlier MP4")
    log = _fake_imageio(monkeypatch, fail_at=2)
    with pytest.raises(OSError, match="No space left on device"):
        viz.render_series(run_dir, path, window_size=(201, 301))
    assert (log["frames"], log["closed"]) == (2, 1)
    assert path.read_bytes() == b"the earlier MP4"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.mp4"]


@pytest.mark.parametrize("fps", [1e-300, 0.0, 0.09, 100.5, 1e300, float("inf"), float("nan"),
                                 -10.0, True, "fast"])
def test_fps_out_of_range_is_refused_before_anything(run_dir, tmp_path, monkeypatch, fps):
    def no_rendering():
        raise AssertionError("rendering started")

    monkeypatch.setattr("skfem_granular.viz.animation.require_pyvista", no_rendering)
    path = tmp_path / "run.gif"
    path.write_bytes(b"GIF89a the earlier animation")
    with pytest.raises(ValueError) as info:
        viz.render_series(run_dir, path, fps=fps)
    assert str(info.value) == f"fps = {fps!r}: must be a finite number in [0.1, 100]"
    assert path.read_bytes() == b"GIF89a the earlier animation"
    assert viz.check_fps(0.1) == 0.1 and viz.check_fps(100) == 100.0


def test_output_under_a_file_is_refused_before_rendering(run_dir, tmp_path, monkeypatch):
    def no_rendering():
        raise AssertionError("rendering started")

    monkeypatch.setattr("skfem_granular.viz.animation.require_pyvista", no_rendering)
    monkeypatch.setattr("skfem_granular.viz.frames.require_pyvista", no_rendering)
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    with pytest.raises(ValueError, match=r"'.*a_file' is not a directory"):
        viz.render_frame(run_dir / "flow_00002.vtu", None, blocker / "pic.png")
    with pytest.raises(ValueError, match=r"'.*a_file' is not a directory"):
        viz.render_series(run_dir, blocker / "run.gif")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]
