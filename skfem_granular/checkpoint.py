"""Checkpoints: the whole state of a run in one file, and resuming from it.

A checkpoint holds everything the next step depends on: the scene, the step
count, the fluid state with *both* BDF2 histories (``u_n``, ``u_{n-1}``) and
the particle histories, the DEM state (positions, velocities, BDF2 history,
contact springs), the mesh with its meshing recipe and the reference
positions of the particles on it, the history rows, the counters and the
frames written so far. It is written atomically (temporary file + rename),
so a run killed while writing leaves the previous checkpoint intact.
Resuming rebuilds the coupling from the stored mesh; the running simulation
refactorises at each checkpoint too, so a run resumed from a checkpoint
reproduces the run that wrote it bit for bit (tested).
"""

from __future__ import annotations

import pickle
from pathlib import Path

from .io import atomic_write

FORMAT = "skfem-granular checkpoint 1"
FILENAME = "checkpoint.pkl"


def save(sim, state, k: int, hist, series) -> Path:
    """Write ``checkpoint.pkl`` into the simulation's output directory."""
    data = {
        "format": FORMAT,
        "scene": sim.scene,
        "k": k,
        "state": state,
        "dem": sim.dem.save_state(),
        "mesh": getattr(sim, "mesh", None),
        "mesh_centers": getattr(sim, "mesh_centers", None),
        "mesh_angles": getattr(sim, "mesh_angles", None),
        "history": hist.rows,
        "counters": {"remeshes": sim.remeshes, "retries": sim.retries,
                     "rejections": sim.rejections, "euler_steps": sim.euler_steps},
        "frames": {name: s.frames for name, s in (series or {}).items() if s is not None},
    }
    blob = pickle.dumps(data, protocol=pickle.HIGHEST_PROTOCOL)
    # a resumed run rebuilds the DEM's Verlet neighbour list and refactorises the
    # coupled operator; do both here too, so that the run that wrote the checkpoint and
    # any run resumed from it do the same arithmetic from here on (bitwise equal)
    sim.dem.neighbours.invalidate()
    if getattr(sim, "coupling", None) is not None:
        sim.coupling._a0 = None
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
