"""Translation of the TOML layout of a scene into :class:`~skfem_granular.scene.Scene` arguments."""

from __future__ import annotations

import numpy as np

from ..dem import ContactLaw, Polygon, PrescribedMotion
from ..fluid.properties import Fluid
from ._checks import MAX_ANGLE, MAX_LENGTH, check_keys, num, vec
from .column import COLUMN_OVERLAP_FACTOR, column_particles
from .sections import Effects, MeshSpec, ParticleSpec, TimeSpec

SECTIONS = {"domain", "fluid", "particles", "grid", "contacts", "mesh", "time", "effects",
            "coupling", "output", "gravity", "column"}
PARTICLE_KEYS = {"sides", "radius", "center", "angle", "vertices", "density", "velocity",
                 "angular_velocity", "core_ratio", "motion"}
MOTION_KEYS = {"velocity", "omega", "trajectory"}
GRID_KEYS = {"nx", "ny", "sides", "radius", "spacing", "origin", "density", "core_ratio",
             "jitter", "seed"}
#: largest ``sides`` of a regular polygon (the paper's outlines have 24)
MAX_SIDES = 1000
#: most particles in a scene (``[[particles]]`` and ``[grid]`` together), checked before
#: any of them is built (the bundled scenes have at most 210)
MAX_PARTICLES = 10_000


def _table(name: str, value) -> dict:
    """``value`` if it is a TOML table, else a one-line error naming the section."""
    if not isinstance(value, dict):
        raise ValueError(f"{name} = {value!r}: must be a table ([{name}] section)")
    return value


def _int(where: str, name: str, value, lo: int, hi: int | None = None) -> int:
    """An integer (not a bool) in ``[lo, hi]``."""
    ok = isinstance(value, int) and not isinstance(value, bool) and value >= lo
    if ok and hi is not None:
        ok = value <= hi
    if not ok:
        rng = f"in [{lo}, {hi}]" if hi is not None else f">= {lo}"
        raise ValueError(f"{where}.{name} = {value!r}: must be an integer {rng}")
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
    sides = _int(where, "sides", d["sides"], 3, MAX_SIDES)
    r = num(where, "radius", d["radius"], lo=0, hi=MAX_LENGTH)
    c = vec(where, "center", d["center"], bound=MAX_LENGTH)
    ang = num(where, "angle", d.get("angle", 0.0), lo=-MAX_ANGLE, hi=MAX_ANGLE, lo_open=False)
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
    for key in ("nx", "ny"):
        _int("grid", key, d.get(key), 1, 100)
    sides = _int("grid", "sides", d.get("sides", 6), 3, MAX_SIDES)
    seed = _int("grid", "seed", d.get("seed", 0), 0)
    r = num("grid", "radius", d.get("radius"), lo=0, hi=MAX_LENGTH)
    s = num("grid", "spacing", d.get("spacing", 2.2 * r), lo=2 * r, hi=MAX_LENGTH)
    ox, oy = vec("grid", "origin", d.get("origin"), bound=MAX_LENGTH)
    rho = num("grid", "density", d.get("density", 2650.0), lo=0)
    core = num("grid", "core_ratio", d.get("core_ratio", 0.8), lo=0, hi=1)
    jitter = num("grid", "jitter", d.get("jitter", 0.0), lo=0, lo_open=False, hi=np.pi)
    rng = np.random.default_rng(seed)
    out = []
    for j in range(d["ny"]):
        for i in range(d["nx"]):
            c = (ox + i * s, oy + j * s)
            ang = rng.uniform(-jitter, jitter) if jitter else 0.0
            out.append(ParticleSpec(Polygon.regular(sides, r, center=c, angle=ang), rho,
                                    core_ratio=core))
    return out


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
    check_keys("contacts", c, {"E", "mu", "gamma"})
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


def scene_kwargs(data: dict, base=None) -> dict:
    """Keyword arguments of :class:`Scene` from the TOML dictionary.

    ``base``: the directory relative file names (``column.packing``) are read from.
    """
    if not isinstance(data, dict):
        raise ValueError(
            f"scene = {data!r}: must be a table of sections ({', '.join(sorted(SECTIONS))})"
        )
    check_keys("scene", data, SECTIONS)
    for name in sorted(SECTIONS - {"particles", "gravity"}):
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
    check_keys("domain", dom, {"box", "wall_thickness"})
    kw["domain"] = vec("domain", "box", dom["box"], 4, bound=MAX_LENGTH)
    if "wall_thickness" in dom:
        kw["wall_thickness"] = num("domain", "wall_thickness", dom["wall_thickness"], lo=0,
                                   hi=MAX_LENGTH)
    fl = data.get("fluid")
    if fl is None:
        kw["fluid"] = None
    else:
        check_keys("fluid", fl, {"density", "viscosity"})
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
    if "mesh" in data:
        check_keys("mesh", data["mesh"], {"kind", "delta_l", "sigma", "h", "gap_spacing",
                                          "wake"})
        kw["mesh"] = MeshSpec(**data["mesh"])
    if "time" in data:
        check_keys("time", data["time"], {"t_end", "dt", "dem_dt", "adaptive", "tol", "dt_min"})
        kw["time"] = TimeSpec(**data["time"])
    if "effects" in data:
        check_keys("effects", data["effects"], {"fluid", "gravity", "convection", "contacts",
                                                 "rotation", "remeshing"})
        kw["effects"] = Effects(**data["effects"])
    if "coupling" in data:
        c = data["coupling"]
        check_keys("coupling", c, {"scheme", "remesh_fraction", "mesh_motion", "remesh_travel"})
        kw["coupling"] = c.get("scheme", "monolithic")
        for key in ("remesh_fraction", "mesh_motion", "remesh_travel"):
            if key in c:
                kw[key] = c[key]
    if "output" in data:
        o = data["output"]
        check_keys("output", o, {"directory", "vtu_every", "checkpoint_every"})
        kw["output_dir"] = o.get("directory")
        if kw["output_dir"] is not None and not isinstance(kw["output_dir"], str):
            raise ValueError(f"output.directory = {kw['output_dir']!r}: must be a string (a path)")
        kw["vtu_every"] = o.get("vtu_every", 10)
        kw["checkpoint_every"] = o.get("checkpoint_every", 0)
    return kw
