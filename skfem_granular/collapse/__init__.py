"""The granular column collapse: scene, measurements and figures.

A column prepared with :mod:`skfem_granular.packing` stands against the left wall
of a tank behind a gate removed at ``t = 0`` (:func:`column_scene`, dry or
immersed). The measurements are those collapse experiments report (Lajeunesse et
al. 2005; Rondon, Pouliquen & Aussillous 2011; Kumar, Delenne & Soga): run-out
against time normalised by ``L0`` and ``tau_c = sqrt(H0/g)``, the deposit profile
and its height at the gate, horizontal and vertical kinetic energy, the solid
fraction of the flowing mass, the front's Froude number and the excess pore
pressure along horizontal lines (:mod:`.measures`, :mod:`.series`,
:mod:`.pressure`); :mod:`.plots` draws them, :mod:`.laws` holds the published
dry run-out laws and :func:`run_dry` runs a dry collapse until the deposit is at rest.
"""

from . import plots
from .dry import DryCollapse, run_dry
from .laws import DRY_LAWS, dry_runout
from .measures import (
    deposit_profile,
    flowing_solid_fraction,
    front_froude,
    front_position,
    front_speed,
    front_vertex,
    grain_outlines,
    height_at,
    kinetic_energies,
    local_outlines,
    mass_front,
    masses,
    normalised_runout,
    realisations,
)
from .pressure import excess_pressure, flow_pressure, frame_pressure, line_points, reference_point
from .series import collapse_series, history_columns, initial_column
from .setup import FRICTION, column_scene, column_toml, tank_size, time_scale

__all__ = ["DRY_LAWS", "FRICTION", "DryCollapse", "collapse_series", "column_scene", "column_toml",
           "deposit_profile",
           "dry_runout", "excess_pressure", "flow_pressure", "flowing_solid_fraction",
           "frame_pressure", "front_froude", "front_position", "front_speed", "front_vertex",
           "grain_outlines", "height_at",
           "history_columns", "initial_column", "kinetic_energies", "line_points",
           "local_outlines", "mass_front", "masses", "normalised_runout", "plots", "realisations",
           "reference_point", "run_dry", "tank_size", "time_scale"]
