"""The checks of a checkpoint's content: every field this version knows, by shape and range,
each failure one line naming the field (``where: path: problem``)."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import skfem

import meshing

from ..coupled.state import CoupledState


def fail(where, path, problem):
    raise ValueError(f"{where}: {path}: {problem}")


def check_array(where, path, a, shape, *, none=False, dtype=np.float64):
    if a is None and none:
        return
    if not isinstance(a, np.ndarray):
        fail(where, path, f"must be an array{' or None' if none else ''}, got "
                           f"{type(a).__name__}")
    if a.dtype != dtype:
        fail(where, path, f"dtype {a.dtype}: must be {np.dtype(dtype)}")
    if a.shape != tuple(shape):
        fail(where, path, f"shape {a.shape}: must be {tuple(shape)}")


def check_count(where, path, v):
    if not (isinstance(v, int) and not isinstance(v, bool) and v >= 0):
        fail(where, path, f"= {v!r}: must be an integer >= 0")


def check_time(where, path, v, *, none=False):
    if v is None and none:
        return
    if isinstance(v, np.ndarray) and v.shape == () and v.dtype == np.float64:
        v = float(v)  # the DEM's BDF2 history keeps its step as a 0-d array
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) or v < 0:
        fail(where, path, f"= {v!r}: must be a finite number >= 0")


def check_content(data, where, K, rows):
    """Shapes and ranges of the fields this version knows (fields it does not know pass)."""
    check_count(where, "k", data["k"])
    if data["k"] != rows:
        fail(where, "k", f"= {data['k']}: must equal the number of history rows ({rows})")
    check_dem(data["dem"], where, K)
    check_stepper(data["stepper"], where, K)
    check_frames(data["frames"], where)


def check_dem(dem, where, K):
    """The DEM state's arrays against the number of particles."""
    if not isinstance(dem, dict):
        fail(where, "dem", "must be a dict")
    for name, shape in (("q", (3, K)), ("v", (3, K)), ("external_force", (2, K)),
                        ("external_torque", (K,))):
        if name in dem:
            check_array(where, f"dem.{name}", dem[name], shape)
    if "t" in dem:
        check_time(where, "dem.t", dem["t"])
    if "steps" in dem:
        check_count(where, "dem.steps", dem["steps"])
    if "contact_keys" in dem and "contact_ft" in dem:
        keys = dem["contact_keys"]
        check_array(where, "dem.contact_keys", keys, getattr(keys, "shape", ()),
                     dtype=np.int64)
        check_array(where, "dem.contact_ft", dem["contact_ft"], keys.shape)
        if "contact_mr" in dem:
            check_array(where, "dem.contact_mr", dem["contact_mr"], keys.shape)
    bdf2 = dem.get("bdf2")
    if isinstance(bdf2, dict):
        for name in ("q_prev", "v_prev", "a", "a_prev"):
            if name in bdf2:
                check_array(where, f"dem.bdf2.{name}", bdf2[name], (3, K), none=True)
        if "dt_prev" in bdf2:
            check_time(where, "dem.bdf2.dt_prev", bdf2["dt_prev"], none=True)


def check_stepper(st, where, K):
    """The stepper's state: the mesh, the fluid and particle histories."""
    if not isinstance(st, dict):
        fail(where, "stepper", "must be a dict")
    if "steps_taken" in st:
        check_count(where, "stepper.steps_taken", st["steps_taken"])
    for name, v in (st.get("counters") or {}).items():
        check_count(where, f"stepper.counters.{name}", v)
    for name, shape in (("mesh_centers", (2, K)), ("mesh_angles", (K,)),
                        ("coupling_centers", (2, K)), ("travel_poses", (3, K))):
        if name in st:
            check_array(where, f"stepper.{name}", st[name], shape)
    mesh = st.get("mesh")
    fitted = mesh if isinstance(mesh, meshing.BodyFittedMesh) else None
    m = fitted.mesh if fitted is not None else mesh
    if "mesh" in st and not isinstance(m, skfem.MeshTri):
        fail(where, "stepper.mesh", f"must be a mesh, got {type(mesh).__name__}")
    if fitted is not None:
        nodes = fitted.particle_nodes
        if len(nodes) != K:
            fail(where, "stepper.mesh.particle_nodes", f"{len(nodes)} outlines: must be {K}")
        for i, idx in enumerate(nodes):
            if idx.ndim != 1 or idx.dtype.kind != "i" or (
                    idx.size and (idx.min() < 0 or idx.max() >= m.p.shape[1])):
                fail(where, f"stepper.mesh.particle_nodes[{i}]",
                      f"must be vertex indices in [0, {m.p.shape[1]})")
        if fitted.recipe is not None and len(fitted.recipe.particles) != K:
            fail(where, "stepper.mesh.recipe.particles",
                  f"{len(fitted.recipe.particles)} outlines: must be {K}")
    state = st.get("state")
    if "state" in st and not isinstance(state, CoupledState):
        fail(where, "stepper.state", f"must be a CoupledState, got {type(state).__name__}")
    if state is not None and m is not None:
        nv, ne = m.p.shape[1], m.facets.shape[1]
        nu = 2 * (nv + ne)
        fluid = {"u_n": (nu,), "p_n": (nv,), "p_prev": (nv,),
                 "u_prev": (nu,), "du_n": (nu,), "du_prev": (nu,)}
        rigid = {"xi_prev": (3, K), "q_prev": (3, K), "dxi_n": (3, K), "dxi_prev": (3, K),
                 "F_held": (2, K), "T_held": (K,)}
        moving = {"nodes_n": (2, nv), "nodes_prev": (2, nv)}  # ALE: the vertices at t, t_{n-1}
        for name, shape in {**fluid, **rigid, **moving}.items():
            if hasattr(state, name):
                none = name != "u_n"
                check_array(where, f"stepper.state.{name}", getattr(state, name), shape,
                             none=none)
        for name in ("t",):
            check_time(where, f"stepper.state.{name}", getattr(state, name, 0.0))
        for name in ("dt_prev", "dt_next"):
            if hasattr(state, name):
                check_time(where, f"stepper.state.{name}", getattr(state, name), none=True)
        for name in ("since_remesh", "contact_age"):
            if hasattr(state, name):
                check_count(where, f"stepper.state.{name}", getattr(state, name))


def check_frames(frames, where):
    """The frames written so far: ``(t, file)`` of the known series."""
    if not isinstance(frames, dict):
        fail(where, "frames", "must be a dict")
    for name, lst in frames.items():
        if name not in ("flow", "particles"):
            fail(where, f"frames.{name}", "unknown series (flow, particles)")
        pattern = re.compile(rf"^{name}_\d{{5}}\.vtu$")
        if not isinstance(lst, list):
            fail(where, f"frames.{name}", "must be a list of (t, file)")
        for i, fr in enumerate(lst):
            ok = (isinstance(fr, tuple) and len(fr) == 2 and isinstance(fr[1], str)
                  and pattern.match(fr[1]) and not isinstance(fr[0], bool)
                  and isinstance(fr[0], (int, float)))
            if not ok:
                fail(where, f"frames.{name}[{i}]", f"= {fr!r}: must be (t, '{name}_NNNNN.vtu')")


def check_entries(saved, template, path: str, where: str = "checkpoint") -> None:
    """Refuse dict keys in ``saved`` that ``template`` (a fresh object's state) lacks, and back.

    ``template`` is what this version's stepper or DEM hands over
    (``checkpoint_state()``, ``save_state()``), so an entry added to them later is
    expected with no change here.
    """
    if isinstance(template, dict):
        if not isinstance(saved, dict):
            fail(where, path, f"must be a dict, got {type(saved).__name__}")
        extra = sorted(set(saved) - set(template))
        if extra:
            fail(where, f"{path}.{extra[0]}", "unknown key (this version does not have it)")
        missing = sorted(set(template) - set(saved))
        if missing:
            fail(where, f"{path}.{missing[0]}", "missing")
        for k in template:
            check_entries(saved[k], template[k], f"{path}.{k}", where)
    elif dataclasses.is_dataclass(template) and not isinstance(template, type):
        if type(saved) is not type(template):
            fail(where, path, f"must be a {type(template).__name__}, got "
                               f"{type(saved).__name__}")
