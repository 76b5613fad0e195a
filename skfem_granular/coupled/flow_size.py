"""Element sizes that follow the flow as well as the grains (an option of the remesh).

:func:`vorticity` projects the vorticity of the P2 velocity onto the mesh vertices
(lumped L2 projection); :class:`FlowSizing` turns it into a target edge length
``h = eps U / |omega|`` (``U`` the largest speed: the velocity changes by about
``eps U`` across an element where the flow turns), bounded below so that the flow
asks for at most ``budget`` triangles, and hands it to ``meshing`` as plain values
at points (``field_mesh(..., size=(points, values))``), which keeps its own
graded rule wherever that is finer. Set ``CoupledStepper.flow_sizing`` to a
:class:`FlowSizing` (with a ``"field"`` mesh) to grade every remesh by the flow
there; the default is off. Deterministic: the same flow gives the same sizes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def vorticity(space, u: np.ndarray) -> np.ndarray:
    """``dv/dx - du/dy`` at the mesh vertices ``(nv,)`` (lumped L2 projection onto P1).

    ``space`` is a :class:`~skfem_granular.fluid.TaylorHood`, ``u`` its velocity DOFs
    (interleaved x, y). Exact for a velocity linear in space.
    """
    from skfem import ElementTriP1, LinearForm

    sb = space.sb
    p1 = sb.with_element(ElementTriP1())
    ux, uy = sb.interpolate(u[0::2]), sb.interpolate(u[1::2])
    om = uy.grad[0] - ux.grad[1]

    @LinearForm
    def weighted(v, w):
        return w["f"] * v

    @LinearForm
    def mass(v, w):
        return v

    return weighted.assemble(p1, f=om) / mass.assemble(p1)


@dataclass(frozen=True)
class FlowSizing:
    """Target edge lengths from the flow, for a remesh.

    Attributes
    ----------
    eps : float
        Velocity change across an element where the flow turns, as a fraction of the
        largest speed (``0 < eps <= 1``); smaller is finer.
    budget : int
        Most triangles the flow's sizes may ask for: the sizes are at least
        ``sqrt(area / (budget sqrt(3) / 4))`` (``>= 100``).
    """

    eps: float = 0.1
    budget: int = 20_000

    def __post_init__(self):
        if not (isinstance(self.eps, int | float) and 0.0 < self.eps <= 1.0):
            raise ValueError(f"FlowSizing.eps = {self.eps!r}: must be in (0, 1]")
        if not (isinstance(self.budget, int) and self.budget >= 100):
            raise ValueError(f"FlowSizing.budget = {self.budget!r}: must be an integer >= 100")

    def floor(self, space) -> float:
        """The smallest size the budget allows on ``space``'s mesh."""
        area = float(space.pb.dx.sum())
        return float(np.sqrt(area / (self.budget * np.sqrt(3.0) / 4.0)))

    def __call__(self, space, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(points (2, nv), sizes (nv,))`` at the vertices of ``space``'s mesh."""
        om = np.abs(vorticity(space, u))
        nv = space.mesh.p.shape[1]
        speed = np.hypot(u[0::2], u[1::2])
        U = float(speed.max()) if speed.size else 0.0
        extent = float(np.ptp(space.mesh.p, axis=1).max())  # no limit: the domain's size
        if U == 0.0:  # fluid at rest: nothing to resolve
            return space.mesh.p.copy(), np.full(nv, extent)
        h = self.eps * U / np.maximum(om, U / extent)
        return space.mesh.p.copy(), np.clip(h, self.floor(space), extent)
