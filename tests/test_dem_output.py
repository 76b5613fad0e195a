"""Output: VTU outlines + PVD series (meshio) and history tables (dem.output)."""

import csv
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest

from skfem_granular.dem import (
    ContactLaw,
    DEMSystem,
    History,
    Particle,
    Polygon,
    VTUSeries,
    write_outlines_vtu,
)


def scene():
    parts = [Particle(Polygon.regular(6, 0.5e-3, center=(1.0e-3, 0.45e-3)), 2650.0),
             Particle(Polygon.regular(9, 0.5e-3, center=(2.0e-3, 0.6e-3)), 2650.0,
                      velocity=(-0.1, 0.0), core_offset=0.05e-3)]
    return DEMSystem.in_box(parts, (0.0, 0.0, 3e-3, 11e-3), 0.5e-3,
                            law=ContactLaw(E=1e7, mu=0.3, gamma=0.2))


def test_vtu_round_trip(tmp_path):
    s = scene()
    s.advance(1e-3)
    path = tmp_path / "frame.vtu"
    write_outlines_vtu(path, s)
    m = meshio.read(path)
    kinds = np.concatenate(m.cell_data["kind"])
    owners = np.concatenate(m.cell_data["particle"])
    assert sorted(kinds.tolist()) == [0, 0, 1, 1, 2, 2, 2, 2]
    # every outline comes back with its vertices, in order
    expected = {(0, k): o for k, o in enumerate(s.shadow_outlines())}
    expected |= {(1, k): o for k, o in enumerate(s.core_outlines())}
    found = 0
    for block, kind, owner in zip(m.cells, m.cell_data["kind"], m.cell_data["particle"],
                                  strict=True):
        for conn, kd, ow in zip(block.data, kind, owner, strict=True):
            if kd < 2:
                np.testing.assert_allclose(m.points[conn, :2].T, expected[(kd, ow)], rtol=1e-12)
                found += 1
    assert found == 4
    assert set(owners[kinds == 2].tolist()) == {-1, -2, -3, -4}
    vx = np.concatenate(m.cell_data["vx"])
    np.testing.assert_allclose(vx[(kinds == 0) & (owners == 1)], s.velocities[0, 1], rtol=1e-12)


def test_pvd_series(tmp_path):
    s = scene()
    with VTUSeries(tmp_path / "out", "pile") as series:
        for _ in range(3):
            s.advance(2e-4)
            series.write(s)
    root = ET.parse(tmp_path / "out" / "pile.pvd").getroot()
    sets = root.findall("./Collection/DataSet")
    assert [d.get("file") for d in sets] == ["pile_00000.vtu", "pile_00001.vtu", "pile_00002.vtu"]
    np.testing.assert_allclose([float(d.get("timestep")) for d in sets],
                               [2e-4, 4e-4, 6e-4], rtol=1e-12)
    for d in sets:
        assert (tmp_path / "out" / d.get("file")).exists()


def test_history_arrays_and_csv(tmp_path):
    s = scene()
    h = History()
    h.record(s)
    for _ in range(5):
        s.advance(4e-4)
        h.record(s)
    assert len(h) == 6
    assert h.positions.shape == (6, 2, 2) and h.angles.shape == (6, 2)
    np.testing.assert_allclose(h.t, np.arange(6) * 4e-4, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(h.positions[-1], s.positions)
    assert h.kinetic_energy[0] == pytest.approx(s.mass[1] * 0.1**2 / 2, rel=1e-14)
    assert np.all(h.elastic_energy >= 0) and h.contacts.max() >= 1
    path = tmp_path / "hist.csv"
    h.to_csv(path)
    with open(path) as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 12
    last = rows[-1]
    assert int(last["particle"]) == 1
    assert float(last["x"]) == s.positions[0, 1]
    assert float(last["omega"]) == s.angular_velocities[1]
