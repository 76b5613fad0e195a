"""Checkpoints: the whole state of a run in one file, and resuming from it.

A checkpoint holds everything the next step depends on: the scene, the step
count, the fluid state with *both* BDF2 histories (``u_n``, ``u_{n-1}``) and
the particle histories, the DEM state (positions, velocities, BDF2 history,
contact springs), the mesh with its meshing recipe and the reference
positions of the particles on it, the history rows, the counters and the
frames written so far. It is written atomically (temporary file + rename),
so a run killed while writing leaves the previous checkpoint intact.
The stepper hands over its state (``checkpoint_state``) and is rebuilt from it
on resume; it refactorises at each checkpoint too, so a run resumed from a
checkpoint reproduces the run that wrote it bit for bit (tested).
"""

from __future__ import annotations

import pickle
from pathlib import Path

from ..io import atomic_write

FORMAT = "skfem-granular checkpoint 2"
FILENAME = "checkpoint.pkl"


def save(sim, k: int, series) -> Path:
    """Write ``checkpoint.pkl`` into the simulation's output directory after step ``k``."""
    data = {
        "format": FORMAT,
        "scene": sim.scene,
        "k": k,
        "dem": sim.dem.save_state(),
        "stepper": sim.stepper.checkpoint_state(),
        "history": sim.history.rows,
        "frames": {name: s.frames for name, s in (series or {}).items() if s is not None},
    }
    blob = pickle.dumps(data, protocol=pickle.HIGHEST_PROTOCOL)
    path = Path(sim.output_dir) / FILENAME
    return atomic_write(path, lambda tmp: Path(tmp).write_bytes(blob))


def load(directory) -> dict:
    """Read a checkpoint; a clear ValueError for a missing or corrupt file."""
    path = Path(directory) / FILENAME
    if not path.is_file():
        raise ValueError(f"resume: no {FILENAME} in {str(directory)!r} (run with "
                         "output.checkpoint_every > 0 first)")
    try:
        data = pickle.loads(path.read_bytes())
    except Exception as exc:  # any unpickling failure means a corrupt file
        raise ValueError(f"resume: {str(path)!r} is not a readable checkpoint ({exc!r})") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ValueError(f"resume: {str(path)!r} is not a {FORMAT!r} file")
    return data
