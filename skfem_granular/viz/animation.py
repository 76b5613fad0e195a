"""Animations of a run: the frames of its PVD series as an animated GIF or MP4.

:func:`render_series` draws each frame as :func:`.frames.render_frame` does
(pyvista, off-screen); all frames share one colour range and arrow scale.
GIFs are written with Pillow (a pyvista dependency), MP4 needs ``imageio``
and ``imageio-ffmpeg``. The file is written under a temporary name and renamed
when complete, so a failure leaves an earlier file of that name as it was.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .._validate import in_range
from ..io import atomic_write, check_writable, read_pvd
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

#: Frames per second an animation may have: a GIF frame lasts a whole number of
#: hundredths of a second (at most 655.35 s), so no more than 100.
FPS_RANGE = (0.1, 100.0)


def check_fps(fps, name: str = "fps") -> float:
    """``fps`` as a float, or a one-line ``ValueError`` naming ``name`` and :data:`FPS_RANGE`."""
    return in_range(name, fps, *FPS_RANGE)


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
        ``imageio-ffmpeg``). Written to a temporary file next to it and renamed
        when complete: a failure leaves an earlier file of that name as it was.
    field, vectors, density, box, window_size, edges
        As for :func:`render_frame`; the box and the window are the same
        for all frames.
    every : int
        Use every this many frames of the series (the first one always).
    fps : float
        Frames per second of the animation, in :data:`FPS_RANGE` (a GIF's
        frame time is rounded to whole milliseconds, and stored by most
        writers in hundredths of a second).
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
    if not (isinstance(every, int) and not isinstance(every, bool) and every >= 1):
        raise ValueError(f"every = {every!r}: must be an integer >= 1")
    fps = check_fps(fps)
    path_animation = Path(path_animation)
    suffix = path_animation.suffix.lower()
    if suffix not in (".gif", ".mp4"):
        raise ValueError(f"path_animation {str(path_animation)!r}: must end in .gif or .mp4")
    check_writable(path_animation)  # before any rendering
    imageio = _imageio() if suffix == ".mp4" else None
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
    style = dict(field=field, vectors=vectors, density=density, box=view.box, clim=clim,
                 arrow_scale=arrow_scale, edges=edges, z=z_offsets(view))
    series = [(t, flow, outlines_by_time.get(t)) for (t, _), flow in zip(frames, flows,
                                                                         strict=True)]

    def draw_all(emit) -> None:
        _draw_series(pv, view, series, style, emit)

    if imageio is None:
        _write_gif(path_animation, draw_all, fps)
    else:
        _write_mp4(path_animation, draw_all, fps, imageio)
    return path_animation


def _draw_series(pv, view, series, style, emit) -> None:
    """Draw each ``(t, flow, particles file)`` of ``series`` and pass its pixels to ``emit``."""
    pl = new_plotter(pv, view)
    try:
        for t, flow, pfile in series:
            particles = None if pfile is None else read_vtu(pv, pfile, "particles frame")
            pl.suppress_rendering = True  # one render per frame, in snapshot
            pl.clear()
            draw(pl, pv, flow, particles,
                 title=default_title(style["field"], style["vectors"], t), **style)
            emit(snapshot(pl, view))
    finally:
        pl.close()


def _write_gif(path: Path, draw_all, fps: float) -> None:
    """Draw every frame, then write the animated GIF (Pillow) to a temporary file and rename it."""
    from PIL import Image

    frames: list[Image.Image] = []
    draw_all(lambda image: frames.append(
        Image.fromarray(image).quantize(colors=255, dither=Image.Dither.NONE)))
    first, *rest = frames

    def save(tmp) -> None:
        first.save(tmp, save_all=True, append_images=rest, loop=0,
                   duration=int(round(1000 / fps)), disposal=1, optimize=False)

    atomic_write(path, save)


def _imageio():
    """``imageio.v2``, or an ``ImportError`` saying what MP4 output needs."""
    try:
        import imageio.v2 as imageio
        import imageio_ffmpeg  # noqa: F401 (the writer imageio needs for MP4)
    except ImportError as exc:
        raise ImportError(
            f"MP4 output needs imageio and imageio-ffmpeg ({exc}); "
            "pip install imageio imageio-ffmpeg, or write a .gif"
        ) from exc
    return imageio


def _write_mp4(path: Path, draw_all, fps: float, imageio) -> None:
    """Draw the frames straight into an MP4 at a temporary name, renamed when complete."""

    def write(tmp) -> None:
        try:
            writer = imageio.get_writer(tmp, fps=fps, macro_block_size=1)
        except ValueError as exc:  # no writer for MP4 (imageio-ffmpeg without ffmpeg)
            raise ImportError(f"MP4 output needs imageio-ffmpeg and its ffmpeg ({exc}); "
                              "pip install imageio-ffmpeg, or write a .gif") from exc
        try:
            draw_all(lambda image: writer.append_data(_even(image)))
        finally:
            writer.close()

    atomic_write(path, write)


def _even(image) -> np.ndarray:
    """``image`` padded with white to an even width and height (H.264 in yuv420p needs them)."""
    h, w = image.shape[:2]
    return np.pad(image, ((0, h % 2), (0, w % 2), (0, 0)), constant_values=255)
