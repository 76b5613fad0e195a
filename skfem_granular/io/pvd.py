"""Time series of VTU files with a ``.pvd`` index (the collection ParaView and pyvista read).

The index is rewritten atomically after every frame, so a run killed at any
moment leaves a readable series of complete frames.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from .files import atomic_write, check_writable


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

    def __init__(self, path) -> None:
        self.path = Path(path)
        if self.path.suffix != ".pvd":
            raise ValueError(f"path = {str(path)!r}: a time series must end in '.pvd'")
        check_writable(self.path)
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
        from xml.sax.saxutils import quoteattr  # here: it imports urllib.request (~0.02 s)

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
