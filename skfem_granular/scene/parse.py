"""Translation of the TOML layout of a scene into :class:`~skfem_granular.scene.Scene` arguments."""

from __future__ import annotations

import numpy as np

from ..dem import ContactLaw, Polygon, PrescribedMotion
from ..fluid.properties import Fluid
from ._checks import MAX_ANGLE, MAX_LENGTH, MAX_SIDES, check_keys, integer, num, vec
from ._keys import KeyDoc
from .column import COLUMN_OVERLAP_FACTOR, column_particles
from .grid import GridSpec
from .layout import SCENE_DOCS, SECTIONS, TABLES, section
from .sections import DEFAULT_ANGLE, Effects, MeshSpec, ParticleSpec, TimeSpec

__all__ = ["GRID_KEYS", "MAX_PARTICLES", "MAX_SIDES", "MOTION_KEYS", "PARTICLE_KEYS", "SECTIONS",
           "grid_particles", "scene_kwargs"]

#: The keys of a ``[[particles]]`` entry, of its ``motion`` and of ``[grid]`` (from the
#: dataclasses' fields, :mod:`.layout`).
PARTICLE_KEYS = section("particles").keys
MOTION_KEYS = section("particles.motion").keys
GRID_KEYS = section("grid").keys
#: most particles in a scene (``[[particles]]`` and ``[grid]`` together), checked before
#: any of them is built (the bundled scenes have at most 210)
MAX_PARTICLES = 10_000


def _table(name: str, value) -> dict:
    """``value`` if it is a TOML table, else a one-line error naming the section."""
    if not isinstance(value, dict):
        raise ValueError(f"{name} = {value!r}: must be a table ([{name}] section)")
    return value


def _polygon(where: str, d: dict) -> Polygon:
    if "vertices" in d:
        try:
            V = np.asarray(d["vertices"], dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"{where}.vertices = {d['vertices']!r}: must be a (2, N) array of "
                             "numbers, [[x0, x1, ...], [y0, y1, ...]]") from None
        try:
            return Polygon(V, name=where)
        except ValueError as exc:  # Polygon names the particle already
            msg = str(exc)
            raise ValueError(msg if msg.startswith(where) else f"{where}.vertices: {msg}") from None
        except OverflowError:
            raise ValueError(f"{where}.vertices: coordinates too large for floating point "
                             "(give lengths in metres)") from None
    if "sides" not in d or "radius" not in d or "center" not in d:
        raise ValueError(f"{where}: give 'vertices', or 'sides', 'radius' and 'center'")
    sides = integer(where, "sides", d["sides"], 3, MAX_SIDES)
    r = num(where, "radius", d["radius"], lo=0, hi=MAX_LENGTH)
    c = vec(where, "center", d["center"], bound=MAX_LENGTH)
    ang = num(where, "angle", d.get("angle", DEFAULT_ANGLE), lo=-MAX_ANGLE, hi=MAX_ANGLE,
              lo_open=False)
    try:
        return Polygon.regular(sides, r, center=c, angle=ang)
    except ValueError as exc:  # e.g. a radius below the round-off of the centre coordinates
        raise ValueError(f"{where}.radius = {r!r}: {exc}") from None
    except OverflowError:
        raise ValueError(f"{where}.radius = {r!r}: polygon too large for floating point "
                         "(give lengths in metres)") from None


def _motion(where: str, d) -> PrescribedMotion:
    """``motion = {velocity = [U, V], omega = w}`` or ``{trajectory = [[t...], [x...],
    [y...], [angle...]]}`` of a ``[[particles]]`` entry."""
    where = f"{where}.motion"
    if not isinstance(d, dict):
        raise ValueError(f"{where} = {d!r}: must be a table, e.g. {{ velocity = [U, 0.0], "
                         "omega = 0.0 } or { trajectory = [[t...], [x...], [y...], "
                         "[angle...]] }")
    check_keys(where, d, MOTION_KEYS)
    if "trajectory" in d and ("velocity" in d or "omega" in d):
        raise ValueError(f"{where}: give velocity/omega (constant motion) or trajectory, not "
                         "both")
    if "trajectory" in d:
        if callable(d["trajectory"]):  # from_dict in Python: functions only as PrescribedMotion
            raise ValueError(f"{where}.trajectory: must be a (4, n) array (rows t, x, y, angle)"
                             "; pass a function as ParticleSpec(motion=PrescribedMotion(...))")
        kw = {"trajectory": d["trajectory"]}
    else:
        kw = {"velocity": vec(where, "velocity", d.get("velocity", (0.0, 0.0))),
              "omega": num(where, "omega", d.get("omega", 0.0))}
    try:
        return PrescribedMotion(**kw)
    except ValueError as exc:
        msg = str(exc)
        raise ValueError(f"{where}{msg[len('motion'):]}" if msg.startswith("motion")
                         else f"{where}: {msg}") from None


def _particle(where: str, d: dict) -> ParticleSpec:
    if not isinstance(d, dict):
        raise ValueError(f"{where} = {d!r}: must be a table ([[particles]] entry)")
    check_keys(where, d, PARTICLE_KEYS)
    if "density" not in d:
        raise ValueError(f"{where}.density: missing (kg/m^3, > 0)")
    # absurd sizes (1e200 m) overflow inside the polygon checks: one error line, no warnings
    with np.errstate(over="ignore", invalid="ignore", under="ignore"):
        polygon = _polygon(where, d)
    return ParticleSpec(polygon, num(where, "density", d["density"], lo=0),
                        velocity=vec(where, "velocity", d.get("velocity", (0.0, 0.0))),
                        angular_velocity=num(where, "angular_velocity",
                                              d.get("angular_velocity", 0.0)),
                        core_ratio=num(where, "core_ratio", d.get("core_ratio", 1.0), lo=0, hi=1),
                        motion=_motion(where, d["motion"]) if "motion" in d else None)


def grid_particles(d: dict) -> list[ParticleSpec]:
    """An ``nx`` x ``ny`` block of regular polygons (the paper's Section 7 start)."""
    check_keys("grid", _table("grid", d), GRID_KEYS)
    required = {k: d.get(k) for k in ("nx", "ny", "radius", "origin")}  # None: refused
    return GridSpec(**{**d, **required}).particles()


def _check_count(parts: list, grid) -> None:
    """Refuse more than :data:`MAX_PARTICLES` particles before building any."""
    n = len(parts)
    if isinstance(grid, dict):
        nx, ny = grid.get("nx"), grid.get("ny")
        if (isinstance(nx, int) and isinstance(ny, int) and not isinstance(nx, bool)
                and not isinstance(ny, bool) and nx > 0 and ny > 0):
            n += nx * ny
    if n > MAX_PARTICLES:
        raise ValueError(f"particles: {n} in the scene ([[particles]] and [grid]); at most "
                         f"{MAX_PARTICLES}")


def _contact_law(c, column) -> ContactLaw:
    """The ``[contacts]`` table; a column's packing sets (and fixes) the stiffness ``E``."""
    c = _table("contacts", c)
    check_keys("contacts", c, section("contacts").keys)
    # checked here with the TOML field names (and booleans refused as numbers)
    c = {k: num("contacts", k, v, lo=0, lo_open=(k == "E")) for k, v in c.items()}
    if column is not None:
        c = {"E": column.E, **c}
        if c["E"] != column.E:
            raise ValueError(f"contacts.E = {c['E']:g}: must be the column's packing "
                             f"stiffness {column.E:g} (its grains rest with its overlaps)"
                             "; leave it out")
    try:
        return ContactLaw(**c)
    except ValueError as exc:
        raise ValueError(str(exc).replace("ContactLaw.", "contacts.")) from None


def _scene_fields(name: str, d: dict) -> dict:
    """The :class:`Scene` fields a section of the scene's own (``[coupling]``, ...) sets."""
    out = {}
    for field, doc in SCENE_DOCS.items():
        if isinstance(doc, KeyDoc) and doc.section == name and (doc.key or field) in d:
            out[field] = d[doc.key or field]
    return out


def scene_kwargs(data: dict, base=None) -> dict:
    """Keyword arguments of :class:`Scene` from the TOML dictionary.

    ``base``: the directory relative file names (``column.packing``) are read from.
    """
    if not isinstance(data, dict):
        raise ValueError(
            f"scene = {data!r}: must be a table of sections ({', '.join(sorted(SECTIONS))})"
        )
    check_keys("scene", data, SECTIONS)
    for name in sorted(TABLES - {"particles"}):
        if name in data:
            _table(name, data[name])
    parts = data.get("particles", [])
    if isinstance(parts, dict):
        raise ValueError("particles: must be an array of tables ([[particles]], double brackets), "
                         "got a single table ([particles])")
    if not isinstance(parts, list):
        raise ValueError(f"particles = {parts!r}: must be an array of tables ([[particles]])")
    kw = {}
    dom = data.get("domain")
    if not isinstance(dom, dict) or "box" not in dom:
        raise ValueError("domain.box: missing; give [x0, y0, x1, y1] in metres")
    check_keys("domain", dom, section("domain").keys)
    kw["domain"] = vec("domain", "box", dom["box"], 4, bound=MAX_LENGTH)
    if "wall_thickness" in dom:
        kw["wall_thickness"] = num("domain", "wall_thickness", dom["wall_thickness"], lo=0,
                                   hi=MAX_LENGTH)
    fl = data.get("fluid")
    if fl is None:
        kw["fluid"] = None
    else:
        check_keys("fluid", fl, section("fluid").keys)
        try:
            kw["fluid"] = Fluid(**fl)
        except ValueError as exc:
            raise ValueError(str(exc).replace("Fluid.", "fluid.")) from None
    _check_count(parts, data.get("grid"))
    parts = [_particle(f"particles[{i}]", p) for i, p in enumerate(parts)]
    if "grid" in data:
        parts += grid_particles(data["grid"])
    column = None
    if "column" in data:
        grains, column = column_particles(data["column"], kw["domain"], base)
        parts += grains
        kw["overlap_tolerance"] = max(1e-3, COLUMN_OVERLAP_FACTOR * column.max_overlap)
    kw["particles"] = parts
    if "gravity" in data:
        kw["gravity"] = vec("scene", "gravity", data["gravity"])
    if "contacts" in data or column is not None:
        kw["contact_law"] = _contact_law(data.get("contacts", {}), column)
    for name, cls in (("mesh", MeshSpec), ("time", TimeSpec), ("effects", Effects)):
        if name in data:
            check_keys(name, data[name], section(name).keys)
            kw[name] = cls(**data[name])
    for name in ("coupling", "output"):
        if name in data:
            check_keys(name, data[name], section(name).keys)
            kw.update(_scene_fields(name, data[name]))
    out = kw.get("output_dir")
    if out is not None and not isinstance(out, str):
        raise ValueError(f"output.directory = {out!r}: must be a string (a path)")
    return kw
