"""A scene's fluid mesh and coupling: what the coupled stepper is built from."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..dem.polygon import polygon_area
from ..fluid.space import TaylorHood


def outline_areas(outlines) -> np.ndarray:
    """Areas ``(K,)`` of counter-clockwise outlines (shoelace formula)."""
    return np.array([polygon_area(o) for o in outlines])


def outline_edge(outline: np.ndarray, delta_l: float | None) -> float:
    """Mesh edge length on an outline: ``delta_l`` or the longest polygon edge."""
    e = np.linalg.norm(np.roll(outline, -1, axis=1) - outline, axis=0).max()
    return float(min(e, delta_l) if delta_l else e)


@dataclass(frozen=True)
class CoreSizes:
    """Body-frame measures of each particle's core outline (the outline the fluid sees).

    Computed from the outlines in the particles' own frame, so they are the same numbers
    whatever the current pose (a resumed run sees bit-identical buoyancy).

    Attributes
    ----------
    area : (K,) ndarray
        Core areas (buoyancy).
    edge : (K,) ndarray
        Mesh edge length on each outline (:func:`outline_edge`).
    radius : (K,) ndarray
        Bounding radius of each core about its vertices' mean.
    """

    area: np.ndarray
    edge: np.ndarray
    radius: np.ndarray

    @classmethod
    def of(cls, dem, delta_l: float | None) -> CoreSizes:
        """The sizes of the cores of ``dem``'s particles (``delta_l``: the mesh's edge
        length on outlines, None for the polygons' own edges)."""
        p = dem.particles
        cores = [p.core_local[k, : p.core_count[k]].T for k in range(dem.n)]
        return cls(area=outline_areas(cores),
                   edge=np.array([outline_edge(c, delta_l) for c in cores]),
                   radius=np.array([np.linalg.norm(c - c.mean(axis=1, keepdims=True),
                                                   axis=0).max() for c in cores]))


def build_mesh(scene, cores):
    """The fluid mesh of ``scene`` around the particle cores, as a :class:`meshing.BodyFittedMesh`.

    Its recipe lets every remesh build the same kind of mesh around the moved cores.
    ``kind = "auto"`` is ``"graded"`` for one particle and ``"field"`` (graded
    from the nearest core, gaps resolved; docs/meshing.md) for more.
    """
    import meshing

    m = scene.mesh
    kind = m.kind
    if kind == "auto":
        kind = "graded" if len(cores) == 1 else "field"
    options = {"graded": {"sigma": m.sigma, "delta_l": m.delta_l},
               "field": {"sigma": m.sigma, "delta_l": m.delta_l,
                         **({} if m.gap_spacing is None else {"gap_spacing": m.gap_spacing})},
               "uniform": {"h": m.h, "delta_l": m.delta_l},
               "group": {"h": m.h, "sigma": m.sigma, "delta_l": m.delta_l}}[kind]
    return meshing.build(kind, scene.domain, cores, **options)


def build_coupling(scene, mesh, dem, centers=None, terms=None, assembly="compiled"):
    """The coupling object for ``mesh`` (a ``skfem.MeshTri``); ``centers`` (2, K): the
    particles' reference positions on it (default: where the DEM holds them now);
    ``terms``: user forms of the fluid (:class:`~skfem_granular.fluid.UserTerms`);
    ``assembly``: how the built-in blocks are assembled (:class:`TaylorHood`)."""
    from .monolithic import MonolithicCoupling
    from .partitioned import PartitionedCoupling
    from .rigid import CorrectorOptions, RigidBodies
    from .split import SplitCoupling

    space = TaylorHood(mesh, assembly=assembly)
    walls = {"wall": (0.0, 0.0)}
    centers = dem.positions.copy() if centers is None else np.array(centers, dtype=float)
    bodies = RigidBodies(centers, dem.mass.copy(), dem.inertia.copy(),
                         imposed=dem.imposed.copy(), rotation=scene.effects.rotation)
    common = dict(convection=scene.effects.convection, terms=terms)
    if scene.coupling == "monolithic":
        return MonolithicCoupling(space, scene.fluid, walls, bodies,
                                  corrector=CorrectorOptions(newton_tol=scene.newton_tol),
                                  **common)
    if scene.coupling == "split":
        return SplitCoupling(space, scene.fluid, walls, bodies, **common)
    return PartitionedCoupling(space, scene.fluid, walls, bodies, **common)
