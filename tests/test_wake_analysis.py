"""The oscillation analysis (:mod:`skfem_granular.validation.oscillation`) on constructed
signals of known period, amplitude and mean (sampled every 1 ms, as the wake benchmark's
histories)."""

import numpy as np
import pytest

from skfem_granular.validation import oscillation as bench


@pytest.mark.parametrize("phase", [0.0, 0.7, 2.0])
def test_a_sine_gives_its_period_amplitude_mean_and_strouhal_number(phase):
    """``dx = m + A sin(2 pi t / T + phase)`` with T = 0.11 s, A = 340 um, m = -380 um,
    falling at 0.12 m/s: period to 0.2 %, amplitude and mean to 0.5 um (sampling at 1 ms
    with parabolic refinement), Strouhal number d / (T U) = 0.1894 for d = 2.5 mm."""
    t = np.arange(1, 1051) * 1e-3 + 2.5e-4
    T, A, m, U, d = 0.11, 340e-6, -380e-6, 0.12, 2.5e-3
    dx = m + A * np.sin(2.0 * np.pi * t / T + phase)
    o = bench.oscillation(t, dx, -U * np.ones_like(t), d)
    assert o["period"] == pytest.approx(T, rel=2e-3)
    assert o["periods"][0] == pytest.approx(T, rel=5e-3)
    assert o["periods"][1] == pytest.approx(T, rel=5e-3)
    assert o["amplitude"] == pytest.approx(A, abs=0.5e-6)
    assert o["mean"] == pytest.approx(m, abs=0.5e-6)
    assert o["U"] == pytest.approx(U, rel=1e-12)
    assert o["strouhal"] == pytest.approx(d / (T * U), rel=2e-3)
    assert o["extrema"] in (6, 7, 8)             # 0.39 s of window: 7.1 half periods


def test_extrema_alternate_and_skip_the_ends_of_the_record():
    """A cosine from a crest: the record's first sample is no turning point, so the extrema
    are the troughs and crests inside, alternating, at t = (k + 1/2) T / 2 ... and k T."""
    T = 0.1
    t = np.linspace(0.0, 0.42, 421)
    te, ye = bench.extrema(t, np.cos(2.0 * np.pi * t / T))
    np.testing.assert_allclose(te, 0.5 * T * np.arange(1, 9), atol=1e-6)
    np.testing.assert_allclose(ye, (-1.0) ** np.arange(1, 9), atol=1e-4)


def test_too_short_a_window_is_refused():
    t = np.arange(1, 1051) * 1e-3
    dx = np.sin(2.0 * np.pi * t / 0.11)
    with pytest.raises(ValueError, match="window"):
        bench.oscillation(t, dx, np.ones_like(t), 2.5e-3, window=(0.65, 0.75))
