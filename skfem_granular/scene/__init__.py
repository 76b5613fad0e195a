"""Scene: a declarative description of a simulation, built in Python or read from TOML.

A scene names the geometry, the materials, the discretisation, the time span
and the *effects* it needs; :class:`~skfem_granular.simulation.Simulation`
builds only those. Every value is validated on construction and a bad one
raises a :class:`ValueError` with one line naming the field and the allowed
range (``"time.dt = -1: must be a finite number > 0"``).

Modules: :mod:`.sections` (:class:`Effects`, :class:`MeshSpec`,
:class:`TimeSpec`, :class:`ParticleSpec`), :mod:`.grid` (:class:`GridSpec`),
:mod:`.column` (:class:`~.column.ColumnSpec`), :mod:`.layout` (the sections of a
scene file and the dataclass fields their keys are), :mod:`.parse` (TOML
dictionary to :class:`Scene` arguments, :func:`grid_particles`), :mod:`.scene`
(:class:`Scene`), :mod:`.reference` (the scene-file reference page,
:func:`.reference.scene_reference`), :mod:`.catalog` (the scenes shipped in ``library/``:
:func:`bundled`, :func:`bundled_scenes`; ``Scene.bundled(name)`` reads one).

TOML layout (see ``library/single_particle.toml``; ``skfem-granular scenes``
lists the bundled scenes; every key with its type, default, allowed values and
meaning: :func:`.reference.scene_reference`, the docs' scene-file reference)::

    [domain]    box = [x0, y0, x1, y1], wall_thickness
    [fluid]     density, viscosity                  (omit for a dry scene)
    [[particles]] sides, radius, center, angle | vertices; density, velocity,
                angular_velocity, core_ratio, motion = {velocity, omega} |
                {trajectory = [[t...], [x...], [y...], [angle...]]} (imposed motion)
    [grid]      nx, ny, sides, radius, spacing, origin, density, core_ratio, jitter, seed
    [column]    packing (a .npz file of skfem_granular.packing), core_ratio: a column
                against the left wall behind a gate removed at t = 0
    [contacts]  E, mu, gamma
    [mesh]      kind = "auto" | "graded" | "field" | "uniform" | "group", delta_l, sigma,
                h, gap_spacing, wake
    [time]      t_end, dt, dem_dt, adaptive, tol, dt_min, contact_warning
    [effects]   fluid, gravity, convection, contacts, rotation, remeshing
    [coupling]  scheme = "monolithic" | "partitioned", remesh_fraction,
                mesh_motion = "fixed" | "ale", remesh_travel, newton_tol
    [output]    directory, vtu_every, checkpoint_every
    gravity = [gx, gy]                              (top level, before the first section)
"""

from .catalog import bundled, bundled_scenes, first_comment
from .grid import GridSpec
from .parse import (
    GRID_KEYS,
    MAX_SIDES,
    MOTION_KEYS,
    PARTICLE_KEYS,
    SECTIONS,
    grid_particles,
    scene_kwargs,
)
from .scene import Scene
from .sections import Effects, MeshSpec, ParticleSpec, TimeSpec

__all__ = [
    "GRID_KEYS",
    "MAX_SIDES",
    "MOTION_KEYS",
    "PARTICLE_KEYS",
    "SECTIONS",
    "Effects",
    "GridSpec",
    "MeshSpec",
    "ParticleSpec",
    "Scene",
    "TimeSpec",
    "bundled",
    "bundled_scenes",
    "first_comment",
    "grid_particles",
    "scene_kwargs",
]
