"""The collapse experiment's scene: a prepared column in a tank, dry or immersed.

:func:`column_scene` places a :class:`~skfem_granular.packing.Packing` against the
left wall of a tank long and high enough for its run-out, behind a gate removed at
``t = 0`` (the ``[column]`` section of a scene, :mod:`skfem_granular.scene.column`);
the fluid mesh (``effects.fluid = true``) is the default size-field mesh, fine at
the grains' cores and graded towards the remote walls (docs/meshing.md).
"""

from __future__ import annotations

import math
from typing import Any

from ..packing import Packing
from ..scene import Scene

__all__ = ["FRICTION", "column_scene", "column_toml", "tank_size", "time_scale"]

#: contact friction of the collapse: tan 26 deg, Kumar, Delenne & Soga's friction angle
FRICTION = math.tan(math.radians(26.0))


def time_scale(packing: Packing, gravity: float = 9.81) -> float:
    """``tau_c = sqrt(H0 / g)`` of the column."""
    return math.sqrt(packing.height / gravity)


def tank_size(packing: Packing) -> tuple[float, float]:
    """A tank ``(length, height)`` with room for the run-out.

    Length ``L0 (2 + a + 3 a^(2/3))``: more than twice the dry run-out of the
    published laws (``L_inf / L0 ~ 1 + 1.2 a`` below a ~ 2.3, ``1 + 1.9 a^(2/3)`` above);
    height ``H0`` plus the larger of ``H0 / 2`` and 10 ``d_max``.
    """
    a, L0, H0 = packing.aspect, packing.width, packing.height
    return L0 * (2.0 + a + 3.0 * a ** (2.0 / 3.0)), H0 + max(0.5 * H0, 10.0 * packing.d_max)


def column_scene(packing: Packing, *, fluid: bool = True, core_ratio: float = 0.8,
                 mu: float = FRICTION, gamma: float = 0.5, mu_r: float = 0.0, tank=None,
                 t_end: float | None = None, dt: float | None = None,
                 delta_l: float | None = None, name: str = "column",
                 output_dir: str | None = None, vtu_every: int = 50) -> Scene:
    """The collapse of ``packing`` in a tank, dry (``fluid=False``) or in water.

    Parameters
    ----------
    packing : Packing
    fluid : bool
        Water (1000 kg/m^3, 1e-3 Pa s) around the grains, or a dry run (no mesh).
    core_ratio : float
        The fluid's outline of a grain over its contact outline (0.7-0.95 in the
        literature; Kumar et al.'s hydrodynamic radius).
    mu, gamma : float
        Contact friction and damping of the collapse (stiffness: the packing's).
    mu_r : float
        Rolling friction coefficient of the contacts (0: the grains roll freely;
        :class:`~skfem_granular.dem.ContactLaw`).
    tank : (length, height), optional
        Default :func:`tank_size`.
    t_end, dt : float, optional
        Default: ``8 tau_c`` and 1 ms (dry: the history's row interval; the DEM takes
        its stable substeps) or 0.2 ms (immersed: the coupled step).
    delta_l : float, optional
        Mesh edge length on a grain's core (default: a fifth of the mean diameter).
    """
    L, H = tank_size(packing) if tank is None else tank
    t_end = 8.0 * time_scale(packing) if t_end is None else t_end
    dt = (1e-3 if not fluid else 2e-4) if dt is None else dt
    data: dict[str, Any] = {
        "domain": {"box": [0.0, 0.0, L, H], "wall_thickness": packing.d_max},
        "column": {"packing": packing, "core_ratio": core_ratio},
        "contacts": {"E": packing.E, "mu": mu, "gamma": gamma,
                     **({"mu_r": mu_r} if mu_r else {})},
        "time": {"t_end": t_end, "dt": min(dt, t_end)},
        "effects": {"fluid": bool(fluid), "gravity": True, "contacts": True,
                    "rotation": True, "remeshing": bool(fluid)},
        "output": {"directory": output_dir, "vtu_every": vtu_every},
    }
    if fluid:
        data["fluid"] = {"density": 1000.0, "viscosity": 1e-3}
        data["mesh"] = {"delta_l": 0.2 * packing.d_mean if delta_l is None else delta_l}
    if output_dir is None:
        del data["output"]["directory"]
    return Scene.from_dict(data, name=name)


def column_toml(packing: Packing, path, *, fluid: bool = True, core_ratio: float = 0.8) -> str:
    """The TOML text of :func:`column_scene` for the packing saved at ``path``."""
    sc = column_scene(packing, fluid=fluid, core_ratio=core_ratio)
    x0, y0, x1, y1 = sc.domain
    law = sc.contact_law
    lines = [f"# Collapse of a {packing.state} column of {packing.n} grains (a = "
             f"{packing.aspect:.3g}, solid fraction {packing.solid_fraction:.4f}), "
             f"{'in water' if fluid else 'dry'}; gate at x = {packing.width:.6g} m "
             "removed at t = 0",
             "", "[domain]", f"box = [{x0!r}, {y0!r}, {x1!r}, {y1!r}]",
             f"wall_thickness = {sc.wall_thickness!r}", "", "[column]",
             f"packing = {str(path)!r}", f"core_ratio = {core_ratio!r}", "", "[contacts]",
             f"mu = {law.mu!r}", f"gamma = {law.gamma!r}", "", "[time]",
             f"t_end = {sc.time.t_end!r}", f"dt = {sc.time.dt!r}", "", "[effects]",
             f"fluid = {'true' if fluid else 'false'}", "gravity = true", "contacts = true",
             f"remeshing = {'true' if fluid else 'false'}"]
    if fluid:
        lines += ["", "[fluid]", "density = 1000.0", "viscosity = 1.0e-3", "", "[mesh]",
                  f"delta_l = {sc.mesh.delta_l!r}"]
    return "\n".join(lines) + "\n"
