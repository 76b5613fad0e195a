"""The mesh kinds and :func:`build`, which dispatches to the kind's builder.

Each builder module names the kind it builds with :func:`builds`; importing
``meshing`` imports all four. The value types (:mod:`meshing.value`) build
through this table and never import a builder.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any

KINDS = ("graded", "uniform", "group", "field")
"""The mesh kinds :func:`build` knows, one per public builder."""

BUILDERS: dict[str, Callable[..., Any]] = {}
"""The builder of each kind: ``builder(domain, particles, **options)`` returns a
:class:`meshing.BodyFittedMesh`."""


def builds(kind: str) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Decorator: enter the decorated function as the builder of ``kind``."""
    if kind not in KINDS:
        raise ValueError(f"kind: expected one of {', '.join(map(repr, KINDS))}, got {kind!r}")

    def enter(builder: Callable[..., Any]) -> Callable[..., Any]:
        BUILDERS[kind] = builder
        return builder

    return enter


def build(kind: str, domain: object, particles: object, **options: Any) -> Any:
    """Build a body-fitted mesh of a given kind and keep its provenance.

    Parameters
    ----------
    kind
        ``"graded"`` (:func:`meshing.graded_mesh`), ``"uniform"``
        (:func:`meshing.uniform_mesh`), ``"group"`` (:func:`meshing.group_mesh`)
        or ``"field"`` (:func:`meshing.field_mesh`).
    domain, particles
        As for the builder.
    **options
        The builder's keyword arguments (e.g. ``sigma``, ``delta_l``, ``h``,
        ``relax_rounds``); omitted ones take the builder's defaults.

    Returns
    -------
    BodyFittedMesh
        ``.mesh`` is exactly the builder's mesh; ``.recipe`` and
        ``.particle_nodes`` record how it was built and where the particles are.

    Raises
    ------
    ValueError
        For an unknown ``kind`` and for any input the builder rejects.
    TypeError
        For an option the builder does not have.

    Examples
    --------
    >>> import numpy as np, meshing
    >>> th = 2 * np.pi * np.arange(24) / 24
    >>> disk = np.vstack([1.5e-3 + 5e-4 * np.cos(th), 5.5e-3 + 5e-4 * np.sin(th)])
    >>> value = meshing.build("graded", (0, 0, 3e-3, 11e-3), [disk])
    >>> value.recipe.kind, len(value.particle_nodes)
    ('graded', 1)
    >>> bool(np.all(value.mesh.p[:, value.particle_nodes[0]] == disk))
    True
    """
    if not isinstance(kind, str) or kind not in BUILDERS:
        raise ValueError(f"kind: expected one of {', '.join(map(repr, KINDS))}, got {kind!r}")
    builder = BUILDERS[kind]
    accepted = list(inspect.signature(builder).parameters)[2:]
    unknown = [k for k in options if k not in accepted]
    if unknown:
        raise TypeError(f"options: {', '.join(map(repr, unknown))} not accepted by kind "
                        f"{kind!r} (accepted: {', '.join(accepted)})")
    return builder(domain, particles, **options)
