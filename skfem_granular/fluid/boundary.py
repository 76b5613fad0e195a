"""Velocity boundary data by named boundary.

A boundary condition is given per name of ``mesh.boundaries`` as

- a constant ``(u, v)``,
- a callable ``f(x, y) -> (u, v)`` (vectorised over arrays; unsteady solvers
  also accept ``f(x, y, t)``),
- a :class:`RigidMotion` ``u = V + omega x (x - X)``.

Boundaries left out are "do-nothing" (natural) boundaries. P2 velocity DOFs
sit at vertices and edge midpoints, so nodal interpolation reproduces rigid
motions and any quadratic data exactly.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from .._validate import finite_vector


@dataclass(frozen=True)
class RigidMotion:
    """Rigid-body velocity field ``u(x) = V + omega e_z x (x - X)``.

    Parameters
    ----------
    velocity : (2,) array_like
        Translational velocity ``V`` of the reference point, m/s.
    omega : float
        Angular velocity (counter-clockwise positive), rad/s.
    center : (2,) array_like
        Reference point ``X`` (usually the centre of mass).
    """

    velocity: tuple = (0.0, 0.0)
    omega: float = 0.0
    center: tuple = (0.0, 0.0)

    def __post_init__(self):
        for attr in ("velocity", "center"):
            v = finite_vector(f"RigidMotion.{attr}", getattr(self, attr))
            object.__setattr__(self, attr, (float(v[0]), float(v[1])))
        omega = np.asarray(self.omega, dtype=object)
        try:
            value = float(omega) if omega.ndim == 0 else np.nan
        except (TypeError, ValueError):
            value = np.nan
        if not np.isfinite(value) or isinstance(self.omega, bool | str):
            raise ValueError(f"RigidMotion.omega = {self.omega!r}: must be a finite number")
        object.__setattr__(self, "omega", value)

    def __call__(self, x, y):
        """Velocity at the points ``(x, y)``."""
        X, Y = self.center
        return (self.velocity[0] - self.omega * (np.asarray(y) - Y),
                self.velocity[1] + self.omega * (np.asarray(x) - X))


def _arity(fn: Callable) -> int:
    try:
        params = inspect.signature(fn).parameters.values()
    except (TypeError, ValueError):
        return 2
    positional = [p for p in params if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    return 3 if len(positional) >= 3 else 2


def evaluate(spec, x: np.ndarray, y: np.ndarray, t: float | None, name: str) -> np.ndarray:
    """Evaluate one boundary condition at points; returns ``(2, n)``.

    ``name`` is the boundary's name (``"body_force"`` for the body force).
    """
    n = x.size
    label = name if name == "body_force" else f"velocity[{name!r}]"
    if isinstance(spec, RigidMotion):
        ux, uy = spec(x, y)
    elif callable(spec):
        args = (x, y, t) if (t is not None and _arity(spec) == 3) else (x, y)
        try:
            val = spec(*args)
        except Exception as exc:  # user code: say where it came from
            raise ValueError(f"{label}: the function raised {exc!r}") from exc
        try:
            ux, uy = val
        except (TypeError, ValueError):
            raise ValueError(f"{label}: the function must return two "
                             f"components (u, v), got {type(val).__name__}") from None
    else:
        ux, uy = finite_vector(label, spec)
    out = np.empty((2, n))
    try:
        out[0] = np.broadcast_to(np.asarray(ux, dtype=float), (n,))
        out[1] = np.broadcast_to(np.asarray(uy, dtype=float), (n,))
    except (TypeError, ValueError):
        raise ValueError(f"{label}: each component must be a number or an array "
                         f"of {n} values (one per point)") from None
    if not np.all(np.isfinite(out)):
        raise ValueError(f"{label}: values contain NaN or inf")
    return out


class DirichletData:
    """Dirichlet DOFs and values of the velocity for a set of named boundaries.

    Parameters
    ----------
    space : TaylorHood
        The discretisation.
    velocity : mapping
        ``{boundary name: spec}``; see the module docstring. Where two
        boundaries share a DOF (a corner), the later entry wins.
    """

    def __init__(self, space, velocity: Mapping):
        if not isinstance(velocity, Mapping):
            raise ValueError("velocity: must be a mapping {boundary name: value}")
        self.space = space
        self.specs = dict(velocity)
        self.dofs_by_name = {}
        for name in self.specs:
            space.check_boundary(name)
            self.dofs_by_name[name] = space.boundary_dofs(name)
        dofs = [d for d in self.dofs_by_name.values()]
        self.dofs = np.unique(np.concatenate(dofs)) if dofs else np.zeros(0, dtype=np.int64)
        # boundary facets not covered by Dirichlet data are open (do-nothing)
        self.closed = bool(np.all(np.isin(space.all_boundary_dofs, self.dofs)))

    @property
    def time_dependent(self) -> bool:
        """Whether any callable takes a time argument."""
        return any(callable(s) and not isinstance(s, RigidMotion) and _arity(s) == 3
                   for s in self.specs.values())

    def values(self, t: float | None = None) -> np.ndarray:
        """Full-length velocity vector holding the boundary values (zero elsewhere)."""
        sp_ = self.space
        u = np.zeros(sp_.nu)
        locs = sp_.velocity_doflocs
        comp = sp_.component
        for name, spec in self.specs.items():
            d = self.dofs_by_name[name]
            vals = evaluate(spec, locs[0, d], locs[1, d], t, name)
            u[d] = vals[comp[d], np.arange(d.size)]
        return u
