"""Accuracy against cost: one scene over a grid of discretisations.

Two studies:

``"single-particle"``
    The paper's sinking particle (the bundled scene ``single_particle``,
    24-gon): uniform meshes at several ``h``, graded meshes at several outline
    resolutions ``delta_l`` and growth factors ``sigma``, several time steps.
    Quantities: ``v_y(t_end)`` and the whole ``v_y`` curve (max deviation).
    No analytic value: errors are against the finest run of the study, named
    in the ``reference`` column (the finest uniform mesh for the mesh
    families, the smallest step on the base graded mesh for the step family).
``"faxen"``
    Steady Stokes drag on a disk (radius 0.2) moving along the centre line of
    a closed channel ``[-3, 3] x [-1, 1]`` (k = 0.2; the Faxen case of
    docs/validation.md), regular n-gons with growing n. Errors are against the
    analytic Faxen value for the *circle*, so they include the polygonal
    outline's error.

Many collapses of a granular column (loose/dense x dry/immersed x core ratio x
seed) are a study of their own: :mod:`.collapse_run` (:class:`CollapseRun`,
:func:`plan_collapse`, :func:`execute_collapse`: one run, continued from its
checkpoint when it was cut off) and :mod:`.collapse` (:func:`run_collapse_study`
on an executor, :func:`summarise_collapses`: mean and spread over seeds).

A further one, on a moving case, has its own module: :mod:`.settling` (the
sedimentation checks, check 7: the settling disk of check 2, its maximum particle Reynolds number
and settling time over outline resolution, grading, time step, remesh
threshold and mesh motion) and :mod:`.settling_plots`; it runs with
``python benchmarks/sedimentation.py --check cost [--smoke]``.

Rounding error, two measures, each named in the table:

- ``mirror``: on a mirror-symmetric mesh with the particle on the symmetry
  line, the force/velocity across the line is rounding alone
  (``|v_x| / |v_y|``, ``|F_y| / |F_x|``); NaN on meshes that are not symmetric;
- ``renumber``: the spread (max - min over the unpermuted run and runs whose
  nodes and elements are randomly renumbered, :func:`renumbered`) of the
  quantity, relative to its size, on any mesh.

Runs are independent tasks on a :class:`concurrent.futures.Executor` (default:
a local process pool, a fresh process per run so its peak memory is its own),
each written to ``<out>/runs/<key>.json`` as it finishes; a rerun skips runs
whose file is there (resume).

Modules (each imports only those above it):

- :mod:`.definitions`: :data:`STUDIES`, :class:`Run`, :func:`plan`,
  :data:`COLUMNS`, :data:`FAXEN`, :func:`faxen_drag`;
- :mod:`.meshes`: :func:`renumbered`, :func:`mirror_symmetric`;
- :mod:`.worker`: :func:`execute`, one run on a worker;
- :mod:`.analysis`: :func:`analyse` (table rows), :func:`fit_order`,
  :func:`orders`, :func:`pareto_front`, :func:`sweet_spot`;
- :mod:`.tables`: :func:`write_tables`; :mod:`.plots`: the figures
  (:func:`all_plots`);
- :mod:`.driver`: :func:`run_study`, :class:`StudyResult`, :func:`load_records`,
  the default executor (:func:`local_pool`), :class:`StudyFolder` (a study's folder is
  its own: not a simulation run's nor another study's, one live writer);
- :mod:`.collapse_run`, :mod:`.collapse`: the collapse study (above).
"""

from .analysis import analyse, fit_order, orders, pareto_front, sweet_spot
from .collapse import CollapseStudy, merge_records, run_collapse_study, summarise_collapses
from .collapse_run import (
    CollapseRun,
    cached_packing,
    check_folder,
    execute_collapse,
    plan_collapse,
)
from .definitions import COLUMNS, FAXEN, SCENE, STUDIES, Run, faxen_drag, plan
from .driver import StudyFolder, StudyResult, load_records, local_pool, run_study
from .meshes import mirror_symmetric, renumbered
from .plots import STYLE, all_plots, plot_convergence, plot_fig2, plot_pareto
from .tables import write_tables
from .worker import execute

__all__ = [
    "COLUMNS",
    "CollapseRun",
    "CollapseStudy",
    "FAXEN",
    "SCENE",
    "STUDIES",
    "STYLE",
    "Run",
    "StudyFolder",
    "StudyResult",
    "all_plots",
    "analyse",
    "cached_packing",
    "check_folder",
    "execute",
    "execute_collapse",
    "faxen_drag",
    "fit_order",
    "load_records",
    "local_pool",
    "merge_records",
    "mirror_symmetric",
    "orders",
    "pareto_front",
    "plan",
    "plan_collapse",
    "plot_convergence",
    "plot_fig2",
    "plot_pareto",
    "renumbered",
    "run_collapse_study",
    "run_study",
    "summarise_collapses",
    "sweet_spot",
    "write_tables",
]
