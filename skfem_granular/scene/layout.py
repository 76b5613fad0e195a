"""The layout of a scene file: its sections, and the dataclass whose fields each one's keys are.

Every section's keys come from :func:`~skfem_granular.scene._keys.toml_keys`: the
fields of a dataclass (:func:`dataclasses.fields`) and the table beside it that
gives each field's TOML name, type, unit, allowed values and meaning. The
parser (:mod:`.parse`) accepts exactly these keys and the reference page
(:mod:`.reference`) lists them, so the two cannot drift apart. The tables of
classes defined elsewhere (:class:`~skfem_granular.fluid.Fluid`,
:class:`~skfem_granular.dem.ContactLaw`, :class:`~skfem_granular.dem.PrescribedMotion`)
and of the :class:`~skfem_granular.scene.Scene`'s own fields live here; the
scene's section classes carry theirs (:data:`.sections.TIME_DOCS`, ...).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..dem import ContactLaw, PrescribedMotion
from ..fluid.properties import MAX_DENSITY, VISCOSITY_RANGE, Fluid
from ._checks import MAX_LENGTH
from ._keys import Docs, KeyDoc, check_table, key_names, toml_keys
from .column import COLUMN_DOCS, ColumnSpec
from .grid import GRID_DOCS, GridSpec
from .sections import (
    EFFECTS_DOCS,
    MESH_DOCS,
    PARTICLE_DOCS,
    TIME_DOCS,
    Effects,
    MeshSpec,
    ParticleSpec,
    TimeSpec,
)

__all__ = ["CONTACT_DOCS", "FLUID_DOCS", "LAYOUT", "MOTION_DOCS", "SCENE_DOCS", "SECTIONS",
           "TABLES", "Section", "section"]

#: The TOML keys of ``[fluid]``: one per field of :class:`~skfem_granular.fluid.Fluid`.
FLUID_DOCS: Docs = {
    "density": KeyDoc("float", "fluid density", f"> 0 and <= {MAX_DENSITY:g}", "kg/m^3"),
    "viscosity": KeyDoc("float", "dynamic viscosity",
                        f"in [{VISCOSITY_RANGE[0]:g}, {VISCOSITY_RANGE[1]:g}]", "Pa s"),
}

#: The TOML keys of ``[contacts]``: the fields of :class:`~skfem_granular.dem.ContactLaw`
#: a scene file sets (the others keep their defaults).
CONTACT_DOCS: Docs = {
    "E": KeyDoc("float", "contact stiffness (2D Young's modulus); a [column] sets it from its "
                "packing", "> 0", "Pa"),
    "mu": KeyDoc("float", "Coulomb friction coefficient", ">= 0"),
    "gamma": KeyDoc("float", "dimensionless normal damping (0: elastic contacts)", ">= 0"),
    "gamma_t": None,
    "kt_ratio": None,
    "damping_cap": None,
    "mu_r": KeyDoc("float", "rolling friction coefficient: contacts resist rolling with a "
                   "torque up to mu_r times the rolling radius times the normal force "
                   "(elastic-plastic spring-dashpot; 0: free rolling)", ">= 0"),
    "eta_r": KeyDoc("float", "rolling damping: fraction of the rolling spring's critical "
                    "damping", ">= 0"),
}

#: The TOML keys of a particle's ``motion = {...}``: the fields of
#: :class:`~skfem_granular.dem.PrescribedMotion`.
MOTION_DOCS: Docs = {
    "velocity": KeyDoc("[float, float]", "constant velocity of the centroid from t = 0",
                       "2 finite numbers", "m/s"),
    "omega": KeyDoc("float", "constant angular velocity (counter-clockwise)",
                    "a finite number", "rad/s"),
    "trajectory": KeyDoc("[[float, ...], ...]", "instead of velocity and omega: rows t, x, y, "
                         "angle of the centroid's path, from the particle's pose at t = 0 to "
                         "time.t_end", "(4, n), n >= 2, t increasing", "s, m, m, rad"),
}

_BOX = f"4 finite numbers within +-{MAX_LENGTH:g}, x1 > x0, y1 > y0"
#: Where the :class:`~skfem_granular.scene.Scene`'s own fields are written: one entry per
#: field (``section = ""``: a top-level key). ``Scene`` checks this table against its
#: fields when its module is imported.
SCENE_DOCS: Docs = {
    "domain": KeyDoc("[float, float, float, float]", "the fluid box [x0, y0, x1, y1]", _BOX,
                     "m", key="box", section="domain"),
    "particles": None,
    "fluid": None,
    "gravity": KeyDoc("[float, float]", "gravitational acceleration", "2 finite numbers",
                      "m/s^2", section=""),
    "wall_thickness": KeyDoc("float", "thickness of the DEM walls around the box",
                             f"> 0 and <= {MAX_LENGTH:g}", "m", section="domain"),
    "contact_law": None,
    "mesh": None,
    "time": None,
    "effects": None,
    "coupling": KeyDoc("string", "monolithic: fluid and rigid particle velocities in one "
                       "system; split: pressure correction, the rigid velocities implicit "
                       "(many grains); partitioned: the paper's scheme",
                       '"monolithic", "split" or "partitioned"', key="scheme",
                       section="coupling"),
    "remesh_fraction": KeyDoc("float", "fixed mesh: remesh when a particle has moved by this "
                              "fraction of its outline edge", "> 0 and <= 1",
                              section="coupling"),
    "mesh_motion": KeyDoc("string", "\"auto\": \"ale\" with the monolithic and split "
                          "couplings, \"fixed\" with the partitioned one; \"ale\": the mesh "
                          "moves with the particles",
                          '"auto", "ale" or "fixed" ("ale" needs "monolithic" or "split")',
                          section="coupling"),
    "remesh_travel": KeyDoc("float", "moving mesh: remesh when a particle has travelled this "
                            "many radii from where its mesh was built", "> 0 and <= 100",
                            section="coupling"),
    "mesh_repair": KeyDoc("string", "moving mesh: \"flips\": flip edges of the mesh in use "
                          "when a few triangles ask for a remesh (a new mesh only when flips "
                          "cannot); \"none\": a new mesh; \"auto\": flips with the split "
                          "coupling", '"auto", "flips" or "none"', section="coupling"),
    "newton_tol": KeyDoc("float", "monolithic coupling: the corrector of a step stops when its "
                         "update is below this fraction of the velocity scale",
                         "> 0 and <= 0.001", section="coupling"),
    "output_dir": KeyDoc("string", "where the run writes (relative to the current "
                         "directory); not given: nowhere", "a directory path", key="directory",
                         section="output"),
    "vtu_every": KeyDoc("integer", "write the flow and outlines every this many steps (0: the "
                        "last only)", ">= 0", section="output"),
    "checkpoint_every": KeyDoc("integer", "write checkpoint.npz every this many steps (0: "
                               "never)", ">= 0", section="output"),
    "name": None,
    "overlap_tolerance": None,
}


@dataclass(frozen=True)
class Section:
    """A section of the scene file.

    Attributes
    ----------
    name : str
        Its TOML name (``"particles.motion"``: the inline table of a particle;
        ``""``: the top-level keys).
    heading : str
        How the reference page names it.
    intro : str
        One sentence for the reference page.
    docs : dict
        The table of its keys.
    cls : type or None
        The dataclass whose fields its keys are; ``None``: the
        :class:`~skfem_granular.scene.Scene`'s own (``docs`` is :data:`SCENE_DOCS`).
    """

    name: str
    heading: str
    intro: str
    docs: Docs
    cls: type | None = None

    @property
    def keys(self) -> frozenset[str]:
        """The keys the section accepts."""
        if self.cls is None:
            return key_names(self.docs, self.name)
        return frozenset(toml_keys(self.cls, self.docs))


#: The sections, in the order of the reference page.
LAYOUT = (
    Section("", "Top level", "Keys before the first section.", SCENE_DOCS),
    Section("domain", "[domain]", "The fluid box and the DEM walls around it.", SCENE_DOCS),
    Section("fluid", "[fluid]", "The Newtonian fluid; leave the section out for a dry scene.",
            FLUID_DOCS, Fluid),
    Section("particles", "[[particles]]", "One table per particle: a polygon given by its "
            "vertices or as a regular polygon.", PARTICLE_DOCS, ParticleSpec),
    Section("particles.motion", "motion = { ... } of a [[particles]] entry",
            "An imposed rigid motion: a constant velocity or a trajectory table.",
            MOTION_DOCS, PrescribedMotion),
    Section("grid", "[grid]", "A block of nx x ny equal regular polygons, added to the "
            "[[particles]].", GRID_DOCS, GridSpec),
    Section("column", "[column]", "A prepared packing against the left wall, behind a gate "
            "removed at t = 0.", COLUMN_DOCS, ColumnSpec),
    Section("contacts", "[contacts]", "The DEM contact law.", CONTACT_DOCS, ContactLaw),
    Section("mesh", "[mesh]", "The fluid mesh.", MESH_DOCS, MeshSpec),
    Section("time", "[time]", "Time span and steps.", TIME_DOCS, TimeSpec),
    Section("effects", "[effects]", "The physics the run includes.", EFFECTS_DOCS, Effects),
    Section("coupling", "[coupling]", "Fluid-particle coupling and the mesh's motion.",
            SCENE_DOCS),
    Section("output", "[output]", "What the run writes, and where.", SCENE_DOCS),
)

for _s in LAYOUT:  # each table has one entry per field of its class (Scene: in scene.py)
    if _s.cls is not None:
        check_table(_s.cls, _s.docs)

#: The sections written as tables (``[[particles]]``: an array of them) at the top level.
TABLES = frozenset(s.name for s in LAYOUT if s.name and "." not in s.name)
#: The keys of the top level: the sections' names and the top-level keys.
SECTIONS = TABLES | LAYOUT[0].keys


def section(name: str) -> Section:
    """The section of that TOML name."""
    for s in LAYOUT:
        if s.name == name:
            return s
    raise KeyError(name)
