"""History tables as pandas frames: the same numbers as the CSV files, in both layouts."""

import numpy as np
import pytest

from skfem_granular.io.table import History

pd = pytest.importorskip("pandas")


def _history(T=4, K=3):
    rng = np.random.default_rng(0)
    h = History(K)
    for n in range(T):
        h.append(t=1e-3 * (n + 1), dt=1e-3, iterations=n + 2, fluid_energy=rng.random(),
                 **{c: rng.random(K) for c in History.PARTICLE_COLUMNS})
    return h


def test_to_pandas_matches_the_csv_and_the_arrays(tmp_path):
    h = _history()
    for layout in ("wide", "long"):
        path = tmp_path / f"{layout}.csv"
        h.to_csv(path, layout=layout)
        frame = h.to_pandas(layout)
        from_csv = pd.read_csv(path)
        assert list(frame.columns) == list(from_csv.columns)
        np.testing.assert_array_equal(frame.to_numpy(dtype=float),
                                      from_csv.to_numpy(dtype=float))
    long = h.to_pandas()
    assert len(long) == 4 * 3 and long["particle"].dtype.kind == "i"
    # the tidy layout pivots back to the (T, K) arrays
    np.testing.assert_array_equal(long.pivot(index="t", columns="particle", values="vx"), h.vx)
    wide = h.to_pandas("wide")
    np.testing.assert_array_equal(wide["y_2"], h.y[:, 2])
    np.testing.assert_array_equal(wide["iterations"], h.iterations)
    with pytest.raises(ValueError, match="layout = 'tall'"):
        h.to_pandas("tall")
