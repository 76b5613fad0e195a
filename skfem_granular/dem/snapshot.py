"""An in-memory copy of everything a DEM step changes, to try a step and take it back."""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any

#: The DEM system's attributes a step changes (besides the particles' poses and velocities),
#: replaced whole on a restore.
REPLACED = ("bdf2", "contact_history", "contacts", "force", "torque", "neighbours")


@dataclass(frozen=True)
class DEMSnapshot:
    """What :func:`take` copied: time and step count, poses and velocities, external
    forces, and the objects named in :data:`REPLACED` (BDF2 and contact histories, the
    last contacts and forces, the neighbour list)."""

    t: float
    steps: int
    q: Any
    v: Any
    external_force: Any
    external_torque: Any
    replaced: dict


def take(system) -> DEMSnapshot:
    """A deep copy of the dynamic state of ``system`` (a :class:`DEMSystem`).

    Unlike :meth:`DEMSystem.save_state` (plain data for checkpoints, after which the
    neighbour list is rebuilt), a snapshot keeps the neighbour list and the last contacts,
    so a system restored from it goes on exactly as the one it was taken from.
    """
    return DEMSnapshot(
        t=system.t, steps=system.steps, q=system.particles.q.copy(),
        v=system.particles.v.copy(), external_force=system.external_force.copy(),
        external_torque=system.external_torque.copy(),
        replaced=copy.deepcopy({name: getattr(system, name) for name in REPLACED}))


def restore(system, snap: DEMSnapshot) -> None:
    """Put ``system`` back into the state of ``snap`` (the snapshot stays usable)."""
    system.t, system.steps = snap.t, snap.steps
    # views of these arrays are handed out (positions, velocities): copied in place
    system.particles.q[...] = snap.q
    system.particles.v[...] = snap.v
    system.external_force[...] = snap.external_force
    system.external_torque[...] = snap.external_torque
    for name, value in copy.deepcopy(snap.replaced).items():
        setattr(system, name, value)
