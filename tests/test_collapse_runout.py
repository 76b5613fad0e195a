"""Dry run-out of a column against the published 2D law, within the measured spread.

References: Kumar (2015, PhD thesis, Cambridge, ch. 4), 2D DEM of disks with rolling
resistance, column against a wall behind a gate, run-out read at the farthest grain in
contact with the main mass: ``(L_inf - L0)/L0 = 1.67 a`` for ``a <~ 2.7``; Lajeunesse,
Monnier & Homsy (2005), quasi-2D channel experiments: ``1.2 a`` for ``a <~ 2.3``
(:mod:`skfem_granular.collapse.laws`).

Tolerances are three sample standard deviations of the run-out over seeds, measured
by ``benchmarks/collapse_factors.py`` (``benchmarks/results/collapse_factors_a0.8.json``,
docs/collapse.md): a collapse is chaotic, one seed is one draw.
"""

import numpy as np
import pytest

from skfem_granular.collapse import dry_runout, realisations, run_dry
from skfem_granular.packing import prepare_column

#: 200 12-gons, a = 0.8, mass front at 20 tau_c: sample sd of (L_inf - L0)/L0 over
#: seeds 0, 1, 2 (1.26, 1.33, 1.43; Kumar's law 1.32-1.36 at their aspects)
SD_200 = 0.09
#: 30 irregular grains, a = 0.8, E = 2e5, mass front at rest: sample sd over seeds 0-5
#: (0.82, 0.75, 0.61, -0.17, 0.78, 0.55; Lajeunesse's law 0.89-1.05)
SD_30 = 0.37


def test_small_irregular_columns_run_out_as_the_quasi_2d_law_on_average():
    """30 irregular grains (soft contacts), seeds 0-5: every deposit comes to rest with its
    mass front behind the gap front, and the mean run-out over the six is Lajeunesse's law
    within three standard errors of the mean (measured: 0.557 +- 0.15 against 0.96; one
    seed's window, 3 SD_30, would admit a column that never spreads and twice the law)."""
    runs = []
    for seed in range(6):
        p = prepare_column(30, 0.8, "dense", shape="irregular", seed=seed, E=2e5, margin=1.0)
        r = run_dry(p)
        assert r.at_rest and r.energy_ratio < 1e-4, seed
        assert r.runout <= r.runout_gap, seed
        runs.append((r.runout, dry_runout(p.aspect)))
    runout = realisations([x for x, _ in runs])
    law = float(np.mean([law for _, law in runs]))
    standard_error = runout["std"] / np.sqrt(runout["count"])
    assert abs(runout["mean"] - law) <= 3 * standard_error, (runout, law)
    assert 3 * standard_error < 0.5 * law  # the window excludes no spread and twice the law
    # regression pins (this library's own runs): the seeds' spread, as measured before
    assert runout["std"] == pytest.approx(SD_30, abs=0.02)


@pytest.mark.slow
def test_200_near_disks_run_out_as_the_2d_dem_law_on_average():
    """200 12-gons, seeds 0-2: the mean mass-front run-out at 20 tau_c is Kumar's 2D DEM
    law within three standard errors of the mean, a window that excludes the quasi-2D
    law of Lajeunesse et al. (1.2 a, 0.36 below Kumar's at a = 0.8); the gap front (grains
    within one width count) is never shorter. Measured 1.26, 1.33, 1.43 (mean 1.34 +-
    0.05) against 1.34."""
    runs = []
    for seed in range(3):
        p = prepare_column(200, 0.8, "dense", seed=seed)
        r = run_dry(p)
        assert r.runout <= r.runout_gap, seed
        runs.append(r.runout)
    runout = realisations(runs)
    law = dry_runout(0.8, "Kumar 2015 (2D DEM)")
    window = 3 * runout["std"] / np.sqrt(runout["count"])
    assert abs(runout["mean"] - law) <= window, (runout, law)
    assert window < abs(law - dry_runout(0.8)), (window, law)  # not Lajeunesse's law too
    # regression pin (this library's own runs): the seeds' spread, as measured before
    assert runout["std"] == pytest.approx(SD_200, abs=0.03)
