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

import copy
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


#: Relative net flux (of the total in- and outflow) above which boundary data
#: of a closed domain are refused. Interpolated smooth divergence-free data
#: stay far below: measured 4e-7 (Taylor-Green tests), 2e-2 only with one
#: element per wavelength.
FLUX_RTOL = 1e-2


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
        # (first vertex, second vertex, midside node, length-scaled outward normal) of the
        # boundary facets, built by the first flux()
        self._flux_geometry: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None

    def moved(self, space) -> DirichletData:
        """The same data on a moved discretisation (``space.moved(p)``): DOFs kept, values
        evaluated at the moved DOF locations."""
        new = copy.copy(self)
        new.space = space
        new._flux_geometry = None
        return new

    @property
    def time_dependent(self) -> bool:
        """Whether any callable takes a time argument."""
        return any(callable(s) and not isinstance(s, RigidMotion) and _arity(s) == 3
                   for s in self.specs.values())

    def values(self, t: float | None = None) -> np.ndarray:
        """Full-length velocity vector holding the boundary values (zero elsewhere).

        Raises
        ------
        ValueError
            When the domain is closed and the data carry a net flux through
            the boundary (more than :data:`FLUX_RTOL` of the total in- and
            outflow): incompressible flow cannot satisfy them.
        """
        sp_ = self.space
        u = np.zeros(sp_.nu)
        locs = sp_.velocity_doflocs
        comp = sp_.component
        for name, spec in self.specs.items():
            d = self.dofs_by_name[name]
            vals = evaluate(spec, locs[0, d], locs[1, d], t, name)
            u[d] = vals[comp[d], np.arange(d.size)]
        if self.closed:
            net, total = self.flux(u)
            if abs(net) > FLUX_RTOL * total:
                when = "" if t is None else f" at t = {t:g}"
                share = abs(net) / total
                raise ValueError(
                    f"velocity: every boundary has velocity data (closed domain), but the data"
                    f"{when} carry a net outflow of {net:.6g} per unit depth ({share:.1%} of "
                    f"the total in- and outflow {total:.6g}); an incompressible flow needs "
                    f"zero net flux: balance the data or leave an outlet out of `velocity` "
                    f"(do-nothing boundary). Boundaries: {list(self.specs)}")
        return u

    def flux(self, u: np.ndarray) -> tuple[float, float]:
        """Net outward flux ``int u.n`` of the velocity ``u`` over the whole boundary, and
        ``int |u.n|`` (Simpson's rule per facet: exact for P2 velocities)."""
        if self._flux_geometry is None:
            mesh = self.space.mesh
            f = mesh.boundary_facets()
            i, j = mesh.facets[:, f]
            e = mesh.p[:, j] - mesh.p[:, i]
            n = np.array([e[1], -e[0]])  # normal times the facet length
            tri = mesh.t[:, mesh.f2t[0, f]]  # orient away from the element's third vertex
            out = (mesh.p[:, i] + mesh.p[:, j]) / 2 - mesh.p[:, tri].mean(axis=1)
            n *= np.sign((n * out).sum(axis=0))
            # scalar P2 nodes: vertices, then one per facet
            self._flux_geometry = (i, j, mesh.p.shape[1] + f, n)
        i, j, m, n = self._flux_geometry

        def un(k):  # interleaved velocity DOFs (2 k, 2 k + 1) of scalar node k
            return u[2 * k] * n[0] + u[2 * k + 1] * n[1]

        q = (un(i) + 4 * un(m) + un(j)) / 6
        aq = (np.abs(un(i)) + 4 * np.abs(un(m)) + np.abs(un(j))) / 6
        return float(q.sum()), float(aq.sum())
