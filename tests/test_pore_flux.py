"""The pore-flux measurement (:mod:`skfem_granular.validation.pore_flux`) on its own:
the line's fluid intervals by construction, and mass conservation through whole lines."""

import numpy as np
import pytest

import meshing
from skfem_granular.validation import pore_flux


def test_fluid_intervals_leave_out_the_polygons_the_line_crosses():
    square = np.array([[0.0, 2.0, 2.0, 0.0], [0.5, 0.5, 1.5, 1.5]])
    triangle = np.array([[0.5, 1.5, 1.0], [1.75, 1.75, 2.5]])  # apex above the top
    assert pore_flux.fluid_intervals(1.0, 2.0, [square]) == [(0.0, 0.5), (1.5, 2.0)]
    assert pore_flux.fluid_intervals(1.0, 2.0, [triangle, square]) == [
        (0.0, 0.5), (1.5, 1.75)]
    assert pore_flux.fluid_intervals(3.0, 2.0, [square]) == [(0.0, 2.0)]  # missed


def test_honeycomb_touches_the_floor_and_itself():
    """Shadows (circumradius R) of the 3 x 3 block touch the floor and their neighbours:
    the cores sit CORE * R from their centres, the bottom row's centres R sqrt(3)/2 up."""
    cores = pore_flux.honeycomb()
    centres = np.array([c.mean(axis=1) for c in cores])
    a = pore_flux.R * np.sqrt(3.0) / 2.0
    assert len(cores) == 9
    assert centres[:, 1].min() == pytest.approx(a, rel=1e-12)
    d = np.linalg.norm(centres[:, None] - centres[None], axis=2)
    assert d[d > 0].min() == pytest.approx(2.0 * a, rel=1e-12)  # flat faces touching
    r = np.linalg.norm(cores[0] - centres[0][:, None], axis=0)
    assert r == pytest.approx(pore_flux.CORE * pore_flux.R, rel=1e-12)


def test_flux_through_whole_lines_is_the_inflow():
    """Steady Stokes on the default field mesh: the flux through a vertical line from floor
    to lid, before, through (pores and above) and behind the block, equals the parabolic
    inflow's 2/3 U_max H within 1e-3 (measured: -2.6e-4, +5.3e-5, -2.9e-5)."""
    cores = pore_flux.honeycomb()
    value = meshing.build("field", pore_flux.BOX, cores, delta_l=0.2e-3)
    H = pore_flux.BOX[3] - pore_flux.BOX[1]
    inflow = 2.0 / 3.0 * pore_flux.U_MAX * H
    for x, pieces in ((3e-3, 1), (pore_flux.X0 + 1.5 * pore_flux.R, 4), (12e-3, 1)):
        q, _ = pore_flux.line_fluxes(value, cores, x=x, top=H)
        assert len(q) == pieces
        assert sum(q) == pytest.approx(inflow, rel=1e-3)
