"""Granular packings prepared with the DEM alone: columns of convex grains, dense or loose.

:func:`prepare_column` pours ``n`` grains (near-disks, hexagons or irregular convex
polygons, sizes uniform in diameter with ``d_max / d_min = size_ratio``) into a box
of the column's width under gravity and waits until they rest; the state
(``"dense"`` or ``"loose"``) names the deposition protocol (:mod:`.protocol`). The
result, a :class:`Packing`, carries its measured solid fraction (shadow area over
window area, away from walls, floor and surface) and saves as a plain ``.npz``
file (:meth:`Packing.save`, :func:`load_packing`). :func:`prepare_to_fraction` reaches a
chosen solid fraction between the two by bisection on the deposition friction.
Knows nothing of meshes or fluids.
"""

from .deposit import GUESS_FRACTION, REST_SPEED, column_width, deposition, prepare_column
from .fraction import clipped_area, solid_fraction
from .grains import SHAPES, diameter_range, grain_outlines
from .packing import Packing, load_packing
from .protocol import PROTOCOLS, Protocol
from .target import DENSEST, prepare_to_fraction

__all__ = ["DENSEST", "GUESS_FRACTION", "PROTOCOLS", "REST_SPEED", "SHAPES", "Packing", "Protocol",
           "clipped_area", "column_width", "deposition", "diameter_range", "grain_outlines",
           "load_packing", "prepare_column", "prepare_to_fraction", "solid_fraction"]
