"""Pictures of a run's output: VTU frames to PNG, PVD series to GIF or MP4.

Renders off-screen with pyvista (the ``plot`` extra:
``pip install 'skfem-granular[plot]'``); nothing here is imported by the rest
of the package. On Linux, unless the caller has set them, importing pyvista
through this package (:func:`require_pyvista`) sets
``VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow`` and
``PYVISTA_OFF_SCREEN=true``, so no X display is needed; the machine needs the
EGL and Mesa libraries (Debian: ``apt-get install --no-install-recommends
libegl1 libegl-mesa0 libgl1-mesa-dri``). Set ``VTK_DEFAULT_OPENGL_WINDOW`` to
``vtkOSOpenGLRenderWindow`` (OSMesa) or ``vtkXOpenGLRenderWindow`` (X, e.g.
under Xvfb) to use those instead.

- :func:`render_frame` (:mod:`.frames`): one flow frame (``flow_*.vtu``) as
  the mesh or a scalar field (speed, pressure, vorticity) with a colour bar,
  optional velocity arrows or streamlines, particle outlines on top.
- :func:`render_series` (:mod:`.animation`): the frames of a run directory
  (``flow.pvd``, ``particles.pvd``) as an animated GIF (Pillow) or MP4
  (imageio-ffmpeg), with one colour scale for all frames.
- :mod:`.layers`: the drawing layers, the fields (:data:`FIELDS`), the
  vector styles (:data:`VECTORS`) and the colours.

The picture shows the fluid box (``box``) at equal x and y scales; particle
cores are filled grey with a black outline, shadow (contact) outlines are
drawn in orange, DEM walls in grey.
"""

from ..io import read_pvd
from ._common import require_pyvista
from .animation import FPS_RANGE, check_fps, render_series
from .frames import Picture, render_frame
from .layers import CORE_EDGE, CORE_FILL, FIELDS, MESH_EDGE, SHADOW_EDGE, VECTORS, WALL_FILL

__all__ = [
    "CORE_EDGE",
    "CORE_FILL",
    "FIELDS",
    "FPS_RANGE",
    "MESH_EDGE",
    "SHADOW_EDGE",
    "VECTORS",
    "WALL_FILL",
    "Picture",
    "check_fps",
    "read_pvd",
    "render_frame",
    "render_series",
    "require_pyvista",
]
