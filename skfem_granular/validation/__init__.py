"""Validation routes that do not depend on the coupled stepper.

:mod:`.terminal`: the terminal settling velocity of a disk from steady
Navier-Stokes solves in the particle's frame
(:func:`terminal_velocity_frame_solve`). :mod:`.measures`: the quantities the
sedimentation benchmarks extract from a run's history (maximum particle
Reynolds number, terminal velocity, kissing and tumbling times, lateral
offset, orientation, angle of repose). :mod:`.curves`: digitised published
curves (package data ``curve_<name>.json``) and their comparison with a run (L2
difference over the fall, time to the floor). :mod:`.dfg`: the unsteady DFG cylinder
benchmarks 2D-2 and 2D-3 (:func:`~.dfg.run_dfg`).
"""

from .dfg import DFGSeries, channel_mesh, dfg2d2_summary, dfg2d3_summary, run_dfg
from .terminal import (
    FrameProblem,
    TerminalResult,
    faxen_drag_coefficient,
    frame_drag,
    frame_mesh,
    terminal_velocity_frame_solve,
)

__all__ = ["DFGSeries", "FrameProblem", "TerminalResult", "channel_mesh", "dfg2d2_summary",
           "dfg2d3_summary", "faxen_drag_coefficient", "frame_drag", "frame_mesh", "run_dfg",
           "terminal_velocity_frame_solve"]
