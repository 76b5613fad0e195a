"""Translation of the TOML layout of a scene into :class:`~skfem_granular.scene.Scene` arguments."""

from __future__ import annotations

import numpy as np

from .dem import ContactLaw, Polygon
from .fluid.properties import Fluid
from .scene import Effects, MeshSpec, ParticleSpec, TimeSpec, _check_keys, _num, _vec

SECTIONS = {"domain", "fluid", "particles", "grid", "contacts", "mesh", "time", "effects",
            "coupling", "output", "gravity"}
PARTICLE_KEYS = {"sides", "radius", "center", "angle", "vertices", "density", "velocity",
                 "angular_velocity", "core_ratio"}
GRID_KEYS = {"nx", "ny", "sides", "radius", "spacing", "origin", "density", "core_ratio",
             "jitter", "seed"}


def _polygon(where: str, d: dict) -> Polygon:
    if "vertices" in d:
        try:
            return Polygon(np.asarray(d["vertices"], dtype=float), name=where)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{where}.vertices: {exc}") from None
    if "sides" not in d or "radius" not in d or "center" not in d:
        raise ValueError(f"{where}: give 'vertices', or 'sides', 'radius' and 'center'")
    sides = d["sides"]
    if not isinstance(sides, int) or sides < 3:
        raise ValueError(f"{where}.sides = {sides!r}: must be an integer >= 3")
    r = _num(where, "radius", d["radius"], lo=0)
    c = _vec(where, "center", d["center"])
    ang = _num(where, "angle", d.get("angle", 0.0))
    return Polygon.regular(sides, r, center=c, angle=ang)


def _particle(where: str, d: dict) -> ParticleSpec:
    _check_keys(where, d, PARTICLE_KEYS)
    if "density" not in d:
        raise ValueError(f"{where}.density: missing (kg/m^3, > 0)")
    return ParticleSpec(_polygon(where, d), _num(where, "density", d["density"], lo=0),
                        velocity=_vec(where, "velocity", d.get("velocity", (0.0, 0.0))),
                        angular_velocity=_num(where, "angular_velocity",
                                              d.get("angular_velocity", 0.0)),
                        core_ratio=_num(where, "core_ratio", d.get("core_ratio", 1.0), lo=0, hi=1))


def grid_particles(d: dict) -> list[ParticleSpec]:
    """An ``nx`` x ``ny`` block of regular polygons (the paper's Section 7 start)."""
    _check_keys("grid", d, GRID_KEYS)
    for key in ("nx", "ny"):
        v = d.get(key)
        if not isinstance(v, int) or not 1 <= v <= 100:
            raise ValueError(f"grid.{key} = {v!r}: must be an integer in [1, 100]")
    sides = d.get("sides", 6)
    if not isinstance(sides, int) or sides < 3:
        raise ValueError(f"grid.sides = {sides!r}: must be an integer >= 3")
    r = _num("grid", "radius", d.get("radius"), lo=0)
    s = _num("grid", "spacing", d.get("spacing", 2.2 * r), lo=2 * r)
    ox, oy = _vec("grid", "origin", d.get("origin"))
    rho = _num("grid", "density", d.get("density", 2650.0), lo=0)
    core = _num("grid", "core_ratio", d.get("core_ratio", 0.8), lo=0, hi=1)
    jitter = _num("grid", "jitter", d.get("jitter", 0.0), lo=0, lo_open=False, hi=np.pi)
    rng = np.random.default_rng(int(d.get("seed", 0)))
    out = []
    for j in range(d["ny"]):
        for i in range(d["nx"]):
            c = (ox + i * s, oy + j * s)
            ang = rng.uniform(-jitter, jitter) if jitter else 0.0
            out.append(ParticleSpec(Polygon.regular(sides, r, center=c, angle=ang), rho,
                                    core_ratio=core))
    return out


def scene_kwargs(data: dict) -> dict:
    """Keyword arguments of :class:`Scene` from the TOML dictionary."""
    _check_keys("scene", data, SECTIONS)
    kw = {}
    dom = data.get("domain")
    if not isinstance(dom, dict) or "box" not in dom:
        raise ValueError("domain.box: missing; give [x0, y0, x1, y1] in metres")
    _check_keys("domain", dom, {"box", "wall_thickness"})
    kw["domain"] = _vec("domain", "box", dom["box"], 4)
    if "wall_thickness" in dom:
        kw["wall_thickness"] = _num("domain", "wall_thickness", dom["wall_thickness"], lo=0)
    fl = data.get("fluid")
    if fl is None:
        kw["fluid"] = None
    else:
        _check_keys("fluid", fl, {"density", "viscosity"})
        try:
            kw["fluid"] = Fluid(**fl)
        except ValueError as exc:
            raise ValueError(str(exc).replace("Fluid.", "fluid.")) from None
    parts = [_particle(f"particles[{i}]", p) for i, p in enumerate(data.get("particles", []))]
    if "grid" in data:
        parts += grid_particles(data["grid"])
    kw["particles"] = parts
    if "gravity" in data:
        kw["gravity"] = _vec("scene", "gravity", data["gravity"])
    if "contacts" in data:
        c = data["contacts"]
        _check_keys("contacts", c, {"E", "mu", "gamma"})
        try:
            kw["contact_law"] = ContactLaw(**c)
        except ValueError as exc:
            raise ValueError(str(exc).replace("ContactLaw.", "contacts.")) from None
    if "mesh" in data:
        _check_keys("mesh", data["mesh"], {"kind", "delta_l", "sigma", "h"})
        kw["mesh"] = MeshSpec(**data["mesh"])
    if "time" in data:
        _check_keys("time", data["time"], {"t_end", "dt", "dem_dt"})
        kw["time"] = TimeSpec(**data["time"])
    if "effects" in data:
        _check_keys("effects", data["effects"], {"fluid", "gravity", "convection", "contacts",
                                                 "rotation", "remeshing"})
        kw["effects"] = Effects(**data["effects"])
    if "coupling" in data:
        c = data["coupling"]
        _check_keys("coupling", c, {"scheme", "remesh_fraction"})
        kw["coupling"] = c.get("scheme", "monolithic")
        if "remesh_fraction" in c:
            kw["remesh_fraction"] = c["remesh_fraction"]
    if "output" in data:
        o = data["output"]
        _check_keys("output", o, {"directory", "vtu_every"})
        kw["output_dir"] = o.get("directory")
        kw["vtu_every"] = o.get("vtu_every", 10)
    return kw
