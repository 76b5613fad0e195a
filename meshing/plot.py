"""Drawing a mesh with its named boundaries coloured (matplotlib)."""

from __future__ import annotations

import numpy as np

from .value import mesh_of


def plot_mesh(mesh, ax=None, boundaries: bool = True, lw: float = 0.4,
              color: str = "0.55", legend: bool = True):
    """Draw a triangle mesh and colour its named boundaries.

    Parameters
    ----------
    mesh
        ``skfem.MeshTri`` (any mesh with ``p``, ``t``, ``facets`` and
        ``boundaries``) or :class:`meshing.BodyFittedMesh` (its mesh is drawn).
    ax
        Matplotlib axes; a new figure is made when ``None``.
    boundaries
        Colour the facets of every named boundary (``"wall"`` is drawn only
        where no more specific name such as ``"left"`` covers it).
    lw, color
        Line width and colour of the element edges.
    legend
        Add a legend of the boundary names.

    Returns
    -------
    matplotlib.axes.Axes
    """
    try:
        import matplotlib.pyplot as plt
        from matplotlib.collections import LineCollection
    except ImportError as err:  # pragma: no cover
        raise ImportError("plot_mesh needs matplotlib: pip install matplotlib") from err
    mesh = mesh_of(mesh)
    if ax is None:
        _, ax = plt.subplots()
    p, t = np.asarray(mesh.p), np.asarray(mesh.t)
    ax.triplot(p[0], p[1], t.T, lw=lw, color=color)
    if boundaries and mesh.boundaries:
        named = dict(mesh.boundaries)
        if "wall" in named and any(k in named for k in ("left", "right", "bottom", "top")):
            named.pop("wall")
        cmap = plt.get_cmap("tab10")
        for i, (name, facets) in enumerate(sorted(named.items())):
            seg = np.transpose(p[:, mesh.facets[:, facets]], (2, 1, 0))
            ax.add_collection(LineCollection(list(seg), colors=[cmap(i % 10)], lw=4 * lw + 1.0,
                                             label=name))
        if legend:
            ax.legend(loc="upper right", fontsize="small", framealpha=0.8)
    ax.set_aspect("equal")
    ax.autoscale_view()
    return ax
