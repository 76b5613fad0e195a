"""Animations of a run: the frames of its PVD series as an animated GIF or MP4.

:func:`render_series` draws each frame as :func:`.frames.render_frame` does
(pyvista, off-screen); all frames share one colour range and arrow scale.
GIFs are written with Pillow (a pyvista dependency), MP4 needs ``imageio``
and ``imageio-ffmpeg``.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..io import read_pvd
from ._common import (
    View,
    check_style,
    default_box,
    default_title,
    field_range,
    new_plotter,
    read_vtu,
    require_pyvista,
    snapshot,
    widen,
    z_offsets,
)
from .layers import draw

if TYPE_CHECKING:
    from PIL import Image


def render_series(
    out_dir,
    path_animation,
    *,
    field: str = "speed",
    vectors: str | None = None,
    every: int = 1,
    fps: float = 10.0,
    density: int = 16,
    box=None,
    window_size=None,
    clim=None,
    edges: bool = False,
    outlines: bool = True,
) -> Path:
    """Render the frames of a run directory as an animated GIF or an MP4.

    Parameters
    ----------
    out_dir : str or Path
        A run's output directory with ``flow.pvd`` (and ``particles.pvd``).
    path_animation : str or Path
        ``*.gif`` (written with Pillow) or ``*.mp4`` (needs ``imageio`` and
        ``imageio-ffmpeg``).
    field, vectors, density, box, window_size, edges
        As for :func:`render_frame`; the box and the window are the same
        for all frames.
    every : int
        Use every this many frames of the series (the first one always).
    fps : float
        Frames per second of the animation.
    clim : (lo, hi), optional
        Colour range; default: the range over all frames used, so colours
        compare across frames. Arrows are scaled by the largest speed of
        all frames too.
    outlines : bool
        Draw the particles of ``particles.pvd`` (when it exists).

    Returns
    -------
    Path
        ``path_animation``.
    """
    check_style(field, vectors, density)
    if not (isinstance(every, int) and every >= 1):
        raise ValueError(f"every = {every!r}: must be an integer >= 1")
    if not fps > 0:
        raise ValueError(f"fps = {fps!r}: must be > 0")
    path_animation = Path(path_animation)
    suffix = path_animation.suffix.lower()
    if suffix not in (".gif", ".mp4"):
        raise ValueError(f"path_animation {str(path_animation)!r}: must end in .gif or .mp4")
    out_dir = Path(out_dir)
    frames = read_pvd(out_dir / "flow.pvd")[::every]
    if not frames:
        raise ValueError(f"{str(out_dir / 'flow.pvd')!r}: no frames")
    outlines_by_time = {}
    if outlines and (out_dir / "particles.pvd").is_file():
        outlines_by_time = dict(read_pvd(out_dir / "particles.pvd"))
    pv = require_pyvista()
    flows = [read_vtu(pv, f, "flow frame") for _, f in frames]
    view = View.fit(
        box if box is not None else default_box(flows[0]), window_size, colour_bar=field != "mesh"
    )
    if field != "mesh" and clim is None:
        ranges = np.array([field_range(f, field, view.box) for f in flows])
        clim = (ranges[:, 0].min(), ranges[:, 1].max())
    clim = None if field == "mesh" else widen(clim)
    arrow_scale = None
    if vectors == "glyphs":
        umax = max(float(np.max(f.point_data["speed"], initial=0.0)) for f in flows)
        h = min(view.box[2] - view.box[0], view.box[3] - view.box[1]) / density
        arrow_scale = 0.9 * h / umax if umax > 0 else 0.0
    writer = _writer(path_animation, fps)
    z = z_offsets(view)
    pl = new_plotter(pv, view)
    try:
        for (t, _), flow in zip(frames, flows, strict=True):
            pfile = outlines_by_time.get(t)
            particles = None if pfile is None else read_vtu(pv, pfile, "particles frame")
            pl.suppress_rendering = True  # one render per frame, in snapshot
            pl.clear()
            draw(
                pl,
                pv,
                flow,
                particles,
                field=field,
                vectors=vectors,
                density=density,
                box=view.box,
                clim=clim,
                arrow_scale=arrow_scale,
                edges=edges,
                title=default_title(field, vectors, t),
                z=z,
            )
            writer.append(snapshot(pl, view))
    finally:
        pl.close()
    writer.close()
    return path_animation


class _GifWriter:
    """Collects frames and writes an animated GIF with Pillow on close."""

    def __init__(self, path: Path, fps: float):
        self.path, self.fps = path, fps
        self.frames: list[Image.Image] = []

    def append(self, image) -> None:
        from PIL import Image

        self.frames.append(Image.fromarray(image).quantize(colors=255,
                                                           dither=Image.Dither.NONE))

    def close(self) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        first, *rest = self.frames
        first.save(
            self.path,
            save_all=True,
            append_images=rest,
            loop=0,
            duration=int(round(1000 / self.fps)),
            disposal=1,
            optimize=False,
        )


class _Mp4Writer:
    def __init__(self, path: Path, fps: float):
        try:
            import imageio.v2 as imageio

            path.parent.mkdir(parents=True, exist_ok=True)
            self.writer = imageio.get_writer(path, fps=fps, macro_block_size=1)
        except (ImportError, ValueError) as exc:
            raise ImportError(
                f"MP4 output needs imageio and imageio-ffmpeg ({exc}); "
                "pip install imageio imageio-ffmpeg, or write a .gif"
            ) from exc

    def append(self, image) -> None:
        # H.264 in yuv420p needs an even width and height: pad with white
        h, w = image.shape[:2]
        pad = ((0, h % 2), (0, w % 2), (0, 0))
        self.writer.append_data(np.pad(image, pad, constant_values=255))

    def close(self) -> None:
        self.writer.close()


def _writer(path: Path, fps: float):
    return _GifWriter(path, fps) if path.suffix.lower() == ".gif" else _Mp4Writer(path, fps)
