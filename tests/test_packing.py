"""Packings prepared with the DEM alone: dense against loose, reproducible, plain-data files.

A 30-grain column (12-gon near-disks, d_max / d_min = 1.8) is poured frictionless
(dense) and with mu = 1 (loose); measured in a window one d_max from the walls,
the floor and the surface. References: the solid fraction lies below 0.9069, the
densest packing of equal disks (Thue), and above 0.70, below any random packing of
2D disks; frictionless deposition packs denser than frictional (Kumar, Delenne & Soga:
83 % against 79 %). Clipped areas against exact polygon areas.
"""

import numpy as np
import pytest
from helpers import column_packing

from skfem_granular.dem import Polygon
from skfem_granular.packing import (
    clipped_area,
    diameter_range,
    grain_outlines,
    load_packing,
    prepare_column,
    prepare_to_fraction,
    solid_fraction,
)

KW = {"E": 2e5, "margin": 1.0}  # soft contacts: large DEM steps for a fast test


@pytest.fixture(scope="module")
def pair():
    return {s: column_packing(s) for s in ("dense", "loose")}


def test_dense_denser_than_loose(pair):
    dense, loose = pair["dense"].solid_fraction, pair["loose"].solid_fraction
    assert 0.70 < loose < dense < np.pi / (2 * np.sqrt(3))
    assert dense - loose > 0.03  # measured 0.087 at seed 3
    for p in pair.values():
        assert p.n == 30 and p.settle_time < 3.0
        assert all(P[0].min() >= 0 and P[1].min() >= 0 for P in p.outlines)
        assert all(P[0].max() <= p.width + 0.05 * p.d_max for P in p.outlines)  # gate overlap


def test_same_seed_same_positions_bit_for_bit(tmp_path):
    first, again = (prepare_column(12, 1.0, "loose", seed=5, **KW) for _ in range(2))
    assert all(np.array_equal(a, b) for a, b in zip(first.outlines, again.outlines, strict=True))
    assert again.solid_fraction == first.solid_fraction
    back = load_packing(first.save(tmp_path / "dense"))
    assert back == first  # every scalar field (wall time aside)
    assert all(np.array_equal(a, b) for a, b in zip(first.outlines, back.outlines, strict=True))


def test_clipped_area_exact():
    sq = Polygon.rectangle(0.0, 0.0, 2.0, 2.0).vertices
    assert clipped_area(sq, (1.0, -1.0, 3.0, 3.0)) == pytest.approx(2.0, rel=1e-14)
    assert clipped_area(sq, (0.5, 0.5, 1.5, 1.0)) == pytest.approx(0.5, rel=1e-14)
    assert clipped_area(sq, (3.0, 3.0, 4.0, 4.0)) == 0.0
    hexagon = Polygon.regular(6, 1.0).vertices  # corners at (+-1, 0): the right half is half
    assert clipped_area(hexagon, (0.0, -2, 2, 2)) == pytest.approx(1.5 * np.sqrt(3) / 2, 1e-13)
    # a square lattice of unit squares, side 0.9: fraction 0.81 in any window of whole cells
    cells = [Polygon.rectangle(i + 0.05, j + 0.05, i + 0.95, j + 0.95).vertices
             for i in range(5) for j in range(5)]
    assert solid_fraction(cells, (1.0, 1.0, 4.0, 3.0)) == pytest.approx(0.81, rel=1e-13)


def test_grain_sizes_follow_the_distribution():
    rng = np.random.default_rng(0)
    d_min, d_max = diameter_range(1e-3, 1.8)
    assert d_max / d_min == pytest.approx(1.8) and (d_min + d_max) / 2 == pytest.approx(1e-3)
    for shape in ("ngon", "hexagon", "irregular"):
        d = np.array([2 * np.sqrt(Polygon(P).area / np.pi)
                      for P in grain_outlines(400, shape, 1e-3, 1.8, rng)])
        assert d_min * (1 - 1e-12) <= d.min() and d.max() <= d_max * (1 + 1e-12)
        assert d.mean() == pytest.approx(1e-3, rel=0.05)  # 400 draws: sd of mean 0.5 %


@pytest.mark.parametrize("kwargs, message", [
    ({"n": 3, "aspect": 10.0}, "the packing cannot fit"),
    ({"n": 30, "aspect": 0.8, "state": "medium"}, "packing.state = 'medium': must be one of"),
    ({"n": 0, "aspect": 0.8}, "packing.n = 0: must be an integer >= 1"),
    ({"n": 30, "aspect": 50.0}, r"packing.aspect = 50.0: must be a number in \[0.05, 20\]"),
    ({"n": 30, "aspect": 0.8, "shape": "star"}, "packing.shape = 'star': must be one of"),
    ({"n": 30, "aspect": 0.8, "size_ratio": 9.0}, r"packing.size_ratio = 9.0: must be"),
])
def test_bad_packing_input_one_line(kwargs, message):
    with pytest.raises(ValueError, match=message) as err:
        prepare_column(**kwargs)
    assert "\n" not in str(err.value)


def test_load_refuses_what_is_not_a_packing(tmp_path):
    with pytest.raises(ValueError, match="not found"):
        load_packing(tmp_path / "none.npz")
    np.savez(tmp_path / "other.npz", a=np.zeros(3))
    with pytest.raises(ValueError, match="not a packing"):
        load_packing(tmp_path / "other.npz")


@pytest.mark.parametrize("target", [0.95, 0.3, "dense"])
def test_solid_fraction_beyond_any_packing_one_line(target):
    with pytest.raises(ValueError, match=r"packing.target_fraction = .*: must be a number in "
                                         r"\(0.5, 0.9069\)") as err:
        prepare_to_fraction(30, 0.8, target)
    assert "\n" not in str(err.value)


@pytest.mark.slow
def test_target_fraction_bisection_and_out_of_reach():
    """The 30-grain column (seed 3) poured with mu = 0 and mu = 1 spans 0.775-0.853; in
    between the fraction is not monotonic in mu (0.820, 0.843, 0.805, 0.846, 0.761, 0.787
    at mu = 1/8 ... 3/4). Bisection reaches a target near its first midpoint's 0.846
    (mu = 0.5), misses the range's middle (0.814: closest 0.787 after 6 depositions) with
    a warning naming the packing returned, and refuses a target beyond the range."""
    kw = {"seed": 3, **KW}
    p = prepare_to_fraction(30, 0.8, 0.84, tol=0.01, **kw)
    assert p.state == "mu=0.5" and abs(p.solid_fraction - 0.84) <= 0.01
    mid = 0.5 * (column_packing("dense").solid_fraction + column_packing("loose").solid_fraction)
    with pytest.warns(UserWarning, match=r"not reached within tol = 0.01 in 6 depositions; "
                                         r"the closest, 0\.78\d\d \(mu=0\.75\)"):
        p = prepare_to_fraction(30, 0.8, mid, tol=0.01, **kw)
    assert abs(p.solid_fraction - mid) > 0.01
    with pytest.raises(ValueError, match="out of reach for these grains, pouring reaches"):
        prepare_to_fraction(30, 0.8, 0.9, **kw)


def test_cli_pack_small_column_measures_half_a_grain_from_the_edges(tmp_path, capsys):
    """``skfem-granular pack 30``: a column too small for a window 2 d_max inside its
    edges is measured 0.5 d_max inside them (the default below 100 grains); the file's
    solid fraction is the shadow area over that window's area, below Thue's 0.9069 and
    above 2D random loose packing's 0.70; a margin asked for explicitly is kept, and one
    that leaves no window is a one-line error."""
    from skfem_granular.cli import main

    path = tmp_path / "c.npz"
    assert main(["pack", "30", "--out", str(path)]) == 0
    pk = load_packing(path)
    d_max = diameter_range(pk.d_mean, pk.size_ratio)[1]
    x0, y0, x1, y1 = pk.window
    assert (x0, y0) == pytest.approx((0.5 * d_max, 0.5 * d_max), rel=1e-12)
    assert x1 == pytest.approx(pk.width - 0.5 * d_max, rel=1e-12)
    assert pk.solid_fraction == solid_fraction(pk.outlines, pk.window)
    assert 0.70 < pk.solid_fraction < 0.9069
    assert "30 grains, dense: solid fraction" in capsys.readouterr().out
    assert main(["pack", "30", "--out", str(tmp_path / "d.npz"), "--margin", "2"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "packing.margin = 2.0" in err


def test_failed_save_keeps_the_earlier_packing(pair, tmp_path, monkeypatch):
    """numpy's savez writing half a file, then failing: the earlier packing file stays byte
    for byte and loads as before, no temporary file is left."""
    from helpers import fail_midway, partial_names

    path = tmp_path / "column.npz"
    assert pair["dense"].save(path) == path
    before = path.read_bytes()
    written = fail_midway(monkeypatch, np, "savez", lambda file, *a: file, data=b"PK\x03\x04")
    with pytest.raises(OSError, match="No space left"):
        pair["loose"].save(tmp_path / "column")  # ".npz" added, as numpy does
    assert written[0].parent == tmp_path and written[0].suffix == ".npz"
    assert path.read_bytes() == before
    assert partial_names(tmp_path) == []
    assert load_packing(path).solid_fraction == pair["dense"].solid_fraction
