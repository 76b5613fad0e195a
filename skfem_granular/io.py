"""Output: VTU files and PVD time series through meshio, written atomically.

Every file is written to a temporary name in the target directory and then
renamed, so that a run killed at any moment leaves each earlier file complete
and readable. The ``.pvd`` collection (a short index of VTU files that
ParaView and pyvista read as a time series) is rewritten the same way after
every frame.
"""

from __future__ import annotations

import functools
import os
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path
from xml.sax.saxutils import quoteattr

import meshio
import numpy as np


def _check_writable(path: Path) -> None:
    parent = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise ValueError(f"output path {str(path)!r}: is a directory")
    if not parent.exists():
        try:
            parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ValueError(f"output path {str(path)!r}: cannot create directory "
                             f"({exc.strerror})") from None
    if not parent.is_dir():
        raise ValueError(f"output path {str(path)!r}: {str(parent)!r} is not a directory")
    if not os.access(parent, os.W_OK):
        raise ValueError(f"output path {str(path)!r}: directory {str(parent)!r} is not writable")


@functools.cache
def _umask() -> int:
    """The process umask (read once: setting it to read it is not thread-safe)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_write(path, write) -> Path:
    """Call ``write(tmp_path)`` and rename the result onto ``path``.

    Parameters
    ----------
    path : str or Path
        Final file name.
    write : callable
        ``write(tmp)`` writes the whole file to the path ``tmp`` (same suffix).
    """
    path = Path(path)
    _check_writable(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}-", suffix=path.suffix, dir=path.parent)
    except OSError as exc:
        raise ValueError(f"output path {str(path)!r}: cannot write ({exc.strerror})") from None
    os.close(fd)
    try:
        write(tmp)
        # mkstemp makes the file private (0600); give it the usual permissions
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def write_vtu(path, points: np.ndarray, cells: dict, point_data: dict | None = None,
              cell_data: dict | None = None) -> Path:
    """Write an unstructured grid to ``path`` (VTU, binary) atomically.

    Parameters
    ----------
    points : (2, N) or (3, N) ndarray
        Point coordinates (``(dim, N)`` as everywhere in this package).
    cells : dict
        ``{meshio cell type: connectivity (n_cells, n_nodes)}``.
    point_data, cell_data : dict, optional
        Fields; vector point data as ``(2, N)`` arrays.
    """
    if Path(path).suffix != ".vtu":
        raise ValueError(f"path = {str(path)!r}: a VTU file must end in '.vtu'")
    pts = np.asarray(points, dtype=float)
    if pts.shape[0] == 2:
        pts = np.vstack([pts, np.zeros(pts.shape[1])])
    pdata = {}
    for k, v in (point_data or {}).items():
        v = np.asarray(v, dtype=float)
        if v.ndim == 2 and v.shape[0] in (2, 3) and v.shape[1] == pts.shape[1]:
            v = v.T
            if v.shape[1] == 2:  # VTK vectors have 3 components
                v = np.hstack([v, np.zeros((v.shape[0], 1))])
        pdata[k] = v
    mesh = meshio.Mesh(pts.T, list(cells.items()), point_data=pdata, cell_data=cell_data or {})
    return atomic_write(path, lambda tmp: meshio.write(tmp, mesh, file_format="vtu"))


class PVDSeries:
    """A time series of VTU files with a ``.pvd`` index, as a context manager.

    Parameters
    ----------
    path : str or Path
        The ``.pvd`` file; frames go next to it as ``<stem>_<k>.vtu``.

    Examples
    --------
    >>> with PVDSeries("out/flow.pvd") as series:          # doctest: +SKIP
    ...     for t, state in evolve(...):
    ...         series.write(t, lambda f: state.save(f))
    """

    def __init__(self, path):
        self.path = Path(path)
        if self.path.suffix != ".pvd":
            raise ValueError(f"path = {str(path)!r}: a time series must end in '.pvd'")
        _check_writable(self.path)
        self.frames: list[tuple[float, str]] = []

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def write(self, t: float, save) -> Path:
        """Write frame at time ``t``: ``save(vtu_path)`` writes the VTU file.

        ``save`` writes to a temporary name that is renamed onto the frame's
        file only when it returns, so an exception inside ``save`` leaves
        the earlier frames and the index as they were.
        """
        try:
            t = float(t)
        except (TypeError, ValueError):
            raise ValueError(f"t = {t!r}: must be a finite number") from None
        if not np.isfinite(t):
            raise ValueError(f"t = {t!r}: must be a finite number")
        name = f"{self.path.stem}_{len(self.frames):05d}.vtu"
        atomic_write(self.path.parent / name, save)
        self.frames.append((t, name))
        self._write_index()
        return self.path.parent / name

    def _write_index(self) -> None:
        lines = ['<?xml version="1.0"?>',
                 '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                 "  <Collection>"]
        lines += [f'    <DataSet timestep="{t!r}" group="" part="0" file={quoteattr(f)}/>'
                  for t, f in self.frames]
        lines += ["  </Collection>", "</VTKFile>", ""]
        text = "\n".join(lines)
        atomic_write(self.path, lambda tmp: Path(tmp).write_text(text))


def read_pvd(path) -> list[tuple[float, Path]]:
    """``(time, file)`` pairs of a PVD collection, in file order.

    Examples
    --------
    >>> read_pvd("out/single_particle/flow.pvd")[:1]  # doctest: +SKIP
    [(0.0, PosixPath('out/single_particle/flow_00000.vtu'))]
    """
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except FileNotFoundError:
        raise ValueError(f"PVD file {str(path)!r}: not found") from None
    except ET.ParseError as exc:
        raise ValueError(f"PVD file {str(path)!r}: not valid XML ({exc})") from None
    return [
        (float(d.get("timestep", "nan")), path.parent / d.get("file")) for d in root.iter("DataSet")
    ]
