"""Accuracy-against-cost studies (skfem_granular.studies): table, orders, plots, resume, executors.

Tiny grids (a few seconds of runs); the full grids are `skfem-granular study ... [--smoke]`.
"""

import csv
import json
import sys
from pathlib import Path

import numpy as np
import pytest
from helpers import only_error_line

from skfem_granular import studies
from skfem_granular.cli import main
from skfem_granular.simulation.folder import FolderInUseError
from skfem_granular.studies import Run

FAXEN_RUNS = [Run("graded", "graded", n_sides=n) for n in (12, 24, 48)] + [
    Run("graded", "graded", n_sides=12, seed=1),
    Run("uniform", "uniform", n_sides=12),
]
WALL = ("wall_time", "wall_meshing", "wall_assembly", "wall_solve", "wall_other", "wall_warmup",
        "peak_rss_mb")


@pytest.fixture(scope="module")
def faxen(tmp_path_factory):
    out = tmp_path_factory.mktemp("faxen")
    return studies.run_study("faxen", out, runs=FAXEN_RUNS, workers=2)


def _table(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_table_has_one_row_per_run_and_all_columns(faxen):
    rows = _table(faxen.out_dir / "table.csv")
    assert tuple(rows[0].keys()) == studies.COLUMNS
    assert [r["key"] for r in rows] == [r.key for r in FAXEN_RUNS]
    for r in rows:
        assert int(r["dofs"]) > int(r["p2_nodes"]) > int(r["vertices"]) > 0
        assert float(r["wall_time"]) > 0 and float(r["peak_rss_mb"]) > 0
        assert r["reference"].startswith("analytic Faxen")
    md = (faxen.out_dir / "table.md").read_text()
    assert md.count("\n| graded |") == 4 and "Fitted orders" in md
    assert sorted(faxen.computed) == sorted(r.key for r in FAXEN_RUNS) and not faxen.failed


def test_faxen_error_falls_with_fitted_order_above_one(faxen):
    # validation case 3: F/(mu U) = 4 pi / (ln(1/k) - 0.9157 + 1.7244 k^2 - ...), k = 0.2
    assert studies.faxen_drag(0.2) == pytest.approx(16.5328, rel=1e-5)
    g = [r for r in faxen.rows if r["family"] == "graded" and not r["seed"]]
    err = [r["error"] for r in g]
    assert all(a > b for a, b in zip(err, err[1:], strict=False)), err
    order = studies.orders(faxen.rows)["graded"]
    assert order > 1.0
    assert studies.fit_order([r["n_sides"] for r in g], err) > 1.0  # in the outline edge too


def test_rounding_measures_are_named_and_small(faxen):
    base = next(r for r in faxen.rows if r["key"] == "graded_graded_n_sides12")
    assert base["mirror_symmetric"] and 0 <= base["rounding_mirror"] < 1e-12
    assert 0 <= base["rounding_renumber"] < 1e-10  # renumbering changes rounding only
    uni = next(r for r in faxen.rows if r["key"] == "uniform_uniform_n_sides12")
    assert not uni["mirror_symmetric"] and np.isnan(uni["rounding_mirror"])


def test_pareto_figure_exists_and_is_not_blank(faxen):
    from PIL import Image

    for name in ("pareto.png", "convergence.png", "fig2.png"):
        img = np.asarray(Image.open(faxen.out_dir / name).convert("L"), dtype=float)
        assert img.shape[0] > 300 and img.shape[1] > 400
        assert img.std() > 10 and (img < 128).mean() > 0.01, name


def test_resume_recomputes_only_the_missing_run(faxen):
    victim = FAXEN_RUNS[1]
    before = json.loads((faxen.out_dir / "runs" / f"{victim.key}.json").read_text())
    (faxen.out_dir / "runs" / f"{victim.key}.json").unlink()
    again = studies.run_study("faxen", faxen.out_dir, runs=FAXEN_RUNS, workers=2, plots=False)
    assert again.computed == [victim.key]
    after = json.loads((faxen.out_dir / "runs" / f"{victim.key}.json").read_text())
    assert after["value"] == pytest.approx(before["value"], rel=1e-12)
    assert len(again.rows) == len(FAXEN_RUNS)


def test_renumbered_mesh_keeps_boundaries_and_drag(faxen):
    import meshing
    import skfem_granular as sg
    from skfem_granular.dem import Polygon

    disk = Polygon.regular(16, 0.2, center=(0.0, 0.0)).vertices
    mesh = meshing.graded_mesh(studies.FAXEN["box"], [disk])
    perm = studies.renumbered(mesh, 7)
    assert not np.array_equal(perm.p, mesh.p)
    for name, facets in mesh.boundaries.items():
        a = np.sort(mesh.p[:, mesh.facets[:, facets]].reshape(4, -1).round(12), axis=1)
        b = np.sort(perm.p[:, perm.facets[:, perm.boundaries[name]]].reshape(4, -1).round(12),
                    axis=1)
        assert a.shape == b.shape and np.allclose(np.sort(a.ravel()), np.sort(b.ravel())), name
    bc = {"wall": (0, 0), "particle0": (1.0, 0.0)}
    F0 = sg.solve_steady(mesh, sg.Fluid(1, 1), bc).force("particle0")
    F1 = sg.solve_steady(perm, sg.Fluid(1, 1), bc).force("particle0")
    assert F1[0] == pytest.approx(F0[0], rel=1e-11)


def test_single_particle_errors_against_the_finest_run(tmp_path):
    t_end = 3e-5
    runs = [Run("uniform", "uniform", h=0.26e-3, dt=1e-5, t_end=t_end),
            Run("graded", "graded", dt=1e-5, t_end=t_end),
            Run("graded", "graded", dt=1e-5, t_end=t_end, seed=1)]
    res = studies.run_study("single-particle", tmp_path, runs=runs, workers=2, plots=False)
    ref, g, _ = res.rows
    assert np.isnan(ref["error"]) and g["reference"] == f"finest run {runs[0].key}"
    assert 0 < g["error"] < 0.1 and g["error_curve"] >= g["error"] * 0.999
    assert g["value"] < 0 and g["mirror_symmetric"] and g["rounding_mirror"] < 1e-12
    assert 0 <= g["rounding_renumber"] < 1e-10


@pytest.mark.filterwarnings("ignore")
def test_dask_executor_gives_the_same_table(faxen, tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        res = studies.run_study("faxen", tmp_path, runs=FAXEN_RUNS, plots=False,
                                executor=client.get_executor())
    assert sorted(res.computed) == sorted(r.key for r in FAXEN_RUNS)
    local = {r["key"]: r for r in _table(faxen.out_dir / "table.csv")}
    table = _table(tmp_path / "table.csv")
    assert len(table) == len(local)
    for r in table:  # rounding spreads are compared only where the values are (4 digits)
        for c in studies.COLUMNS:
            if c not in WALL and not c.startswith("rounding"):
                assert r[c] == local[r["key"]][c], (r["key"], c)
    here = {r["key"]: r["value"] for r in faxen.rows}
    for r in res.rows:
        assert r["value"] == pytest.approx(here[r["key"]], rel=1e-12)


@pytest.mark.parametrize("argv, text", [
    (["study", "sedimentation"], "invalid choice"),
    (["study", "faxen", "--workers", "0"], "--workers"),
    (["study", "faxen", "--workers", "two"], "invalid int"),
])
def test_cli_bad_input_one_line_exit_2(argv, text, capsys, tmp_path):
    assert main(argv + ["--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and text in err[0]


def test_missing_matplotlib_stops_a_study_before_its_first_run(tmp_path, capsys, monkeypatch):
    """A base install (no plot extra): one line naming matplotlib and the extra, exit
    status 2, nothing run and no output folder; the library raises before submitting."""
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib: ImportError

    def no_run(*args, **kwargs):
        raise AssertionError("a run was started")

    monkeypatch.setattr(studies.driver, "local_pool", no_run)
    out = tmp_path / "s"
    assert main(["study", "faxen", "--smoke", "--out", str(out)]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert captured.out == "" and len(err) == 1
    assert "matplotlib" in err[0] and "pip install 'skfem-granular[plot]'" in err[0]
    assert not out.exists()

    class Refuses:
        submit = staticmethod(no_run)

    with pytest.raises(ImportError, match=r"matplotlib.*skfem-granular\[plot\]"):
        studies.run_study("faxen", tmp_path / "lib", runs=FAXEN_RUNS[:1], executor=Refuses())
    assert not (tmp_path / "lib").exists()
    # without figures a study needs no matplotlib (the runs themselves are not started here)
    res = studies.run_study("faxen", tmp_path / "none", runs=[], plots=False)
    assert res.rows == [] and res.files


def test_cli_smoke_study_writes_table_and_figures(tmp_path, capsys):
    out = tmp_path / "fx"
    assert main(["study", "faxen", "--smoke", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "18 runs computed" in text and "graded" in text
    for name in ("table.csv", "table.md", "pareto.png", "convergence.png", "fig2.png"):
        assert (out / name).stat().st_size > 0
    # each process's warm-up (imports, compilation) is reported apart from a run's time;
    # what the runs cost is measured by the benchmarks, not asserted here
    rows = [r for r in _table(out / "table.csv") if r["seed"] == "0"]
    assert all(float(r["wall_warmup"]) > 0 and float(r["wall_time"]) > 0 for r in rows)
    assert main(["study", "faxen", "--smoke", "--out", str(out)]) == 0  # resumed: nothing to do
    assert "0 runs computed, 18 reused" in capsys.readouterr().out


# ---------------------------------------------------------------- files written whole or not at all
def test_failed_table_write_keeps_the_earlier_tables(faxen, tmp_path, monkeypatch):
    """csv's writer failing after one row, then the Markdown write failing halfway: each
    earlier table stays byte for byte, no temporary file is left, the other table is
    written."""
    import csv
    import errno
    import os

    from helpers import fail_midway, partial_names

    studies.write_tables(faxen.rows, tmp_path, "faxen", False)
    before = {n: (tmp_path / n).read_bytes() for n in ("table.csv", "table.md")}
    fewer = faxen.rows[:2]  # a write that got through would change both files

    def writerows(self, rows):
        self.writerow(next(iter(rows)))
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    with monkeypatch.context() as m:
        m.setattr(csv.DictWriter, "writerows", writerows)
        with pytest.raises(OSError, match="No space left"):
            studies.write_tables(fewer, tmp_path, "faxen", False)
    assert {n: (tmp_path / n).read_bytes() for n in before} == before
    assert partial_names(tmp_path) == []
    with monkeypatch.context() as m:
        written = fail_midway(m, Path, "write_text", lambda self, *a: self)
        with pytest.raises(OSError, match="No space left"):
            studies.write_tables(fewer, tmp_path, "faxen", False)
    assert written[0].parent == tmp_path and written[0].name.startswith(".partial-table-")
    assert (tmp_path / "table.md").read_bytes() == before["table.md"]
    assert (tmp_path / "table.csv").read_bytes() != before["table.csv"]  # written before it
    assert partial_names(tmp_path) == []
    studies.write_tables(fewer, tmp_path, "faxen", False)
    assert (tmp_path / "table.md").read_bytes() != before["table.md"]


def test_failed_figure_write_keeps_the_earlier_figure(faxen, tmp_path, monkeypatch):
    """matplotlib's savefig writing half a PNG, then failing: the earlier figure stays byte
    for byte, no temporary file, the figure closed."""
    import matplotlib.pyplot as plt
    from helpers import fail_midway, partial_names
    from matplotlib.figure import Figure

    studies.plot_pareto(faxen.rows, tmp_path / "pareto.png")
    before = (tmp_path / "pareto.png").read_bytes()
    open_figures = plt.get_fignums()  # other tests' figures may be open in this process
    written = fail_midway(monkeypatch, Figure, "savefig", lambda self, fname, *a: fname,
                          data=b"\x89PNG half")
    with pytest.raises(OSError, match="No space left"):
        studies.plot_pareto(faxen.rows[:2], tmp_path / "pareto.png", title="another")
    assert written[0].parent == tmp_path and written[0].name.startswith(".partial-pareto-")
    assert (tmp_path / "pareto.png").read_bytes() == before
    assert partial_names(tmp_path) == [] and plt.get_fignums() == open_figures


def test_failed_record_write_leaves_no_torn_record(faxen, tmp_path, monkeypatch):
    """A run's record whose write fails halfway: no record file (the run is recomputed on
    the next start, not read back torn), no temporary file; an earlier record stays."""
    from helpers import fail_midway, partial_names

    from skfem_granular.studies import driver

    rec = json.loads(next((faxen.out_dir / "runs").glob("*.json")).read_text())
    (tmp_path / "old.json").write_text("the earlier record")
    fail_midway(monkeypatch, Path, "write_text",
                lambda self, *a: self, data=b'{"spec": {"family": ')
    with pytest.raises(OSError, match="No space left"):
        driver._write_json(tmp_path / "new.json", rec)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.json"]
    with pytest.raises(OSError, match="No space left"):
        driver._write_json(tmp_path / "old.json", rec)
    assert (tmp_path / "old.json").read_text() == "the earlier record"
    assert partial_names(tmp_path) == []


# ---------------------------------------------------------------- the study's folder is its own
def _hashes(d):
    import hashlib

    return {str(p.relative_to(d)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(Path(d).rglob("*")) if p.is_file()}


@pytest.fixture
def copy_of(faxen, tmp_path):
    """A copy of the faxen study's folder (the module's own stays as it is)."""
    import shutil

    return shutil.copytree(faxen.out_dir, tmp_path / "faxen")


def test_study_into_a_simulation_runs_folder_is_refused(tmp_path, capsys):
    """One line, exit status 2, also with --overwrite; nothing in the run's folder changes
    (no study.json, no runs/)."""
    from dataclasses import replace

    from skfem_granular.scene import Scene, TimeSpec
    from skfem_granular.simulation import Simulation

    sc = replace(Scene.bundled("single_particle"), time=TimeSpec(2e-5, 1e-5), output_dir=None)
    out = tmp_path / "run"
    Simulation(sc, output_dir=out).run(progress=False)
    before = _hashes(out)
    for extra in ([], ["--overwrite"]):
        assert main(["study", "faxen", "--smoke", "--out", str(out), *extra]) == 2
        assert only_error_line(capsys) == (
            f"skfem-granular: error: output folder {str(out)!r}: holds a simulation run's "
            "output (flow.pvd, flow_00000.vtu, flow_00001.vtu, ...); a study needs a folder "
            "of its own")
        assert _hashes(out) == before and not (out / "runs").exists()


def test_study_into_another_studys_folder_is_refused_unless_overwrite(copy_of, capsys):
    before = _hashes(copy_of)
    (copy_of / "notes.txt").write_text("mine")
    for argv in (["single-particle"], ["faxen", "--smoke"]):  # another study, another grid
        assert main(["study", *argv, "--out", str(copy_of)]) == 2
        assert only_error_line(capsys) == (
            f"skfem-granular: error: output folder {str(copy_of)!r}: holds the output of "
            "another study (faxen: study.json, table.csv, table.md, ...); use --overwrite "
            "(library: overwrite=True) to replace it, or another folder")
    with pytest.raises(FolderInUseError, match="holds the output of another study"):
        studies.run_study("single-particle", copy_of, runs=[])
    assert {k: v for k, v in _hashes(copy_of).items() if k != "notes.txt"} == before
    # replaced: the old study's files removed first (a file not a study's left alone)
    res = studies.run_study("single-particle", copy_of, runs=[], overwrite=True)
    assert res.rows == [] and not list((copy_of / "runs").iterdir())
    assert sorted(p.name for p in copy_of.iterdir()) == ["notes.txt", "runs", "study.json",
                                                         "table.csv", "table.md"]
    assert json.loads((copy_of / "study.json").read_text())["study"] == "single-particle"
    assert (copy_of / "notes.txt").read_text() == "mine"


def test_same_study_continues_and_an_older_folder_is_recognised(copy_of):
    """The same study reads its records back (nothing computed); a folder from before
    study.json is recognised by its table's title: the same study continues it, another is
    refused."""
    again = studies.run_study("faxen", copy_of, runs=FAXEN_RUNS, plots=False)
    assert again.computed == [] and len(again.rows) == len(FAXEN_RUNS)
    (copy_of / "study.json").unlink()
    with pytest.raises(ValueError, match=r"holds the output of another study \(faxen: "):
        studies.run_study("single-particle", copy_of, runs=[])
    again = studies.run_study("faxen", copy_of, runs=FAXEN_RUNS, plots=False)
    assert again.computed == [] and json.loads((copy_of / "study.json").read_text()) == {
        "format": "skfem-granular study", "study": "faxen", "smoke": False}


def test_live_lock_refuses_a_second_study_and_a_run(copy_of, tmp_path, capsys):
    """A study's folder locked by a live process: a study and a run into it are refused in
    one line naming its pid; a run into a study's folder is refused even with --overwrite."""
    import socket
    import subprocess
    import sys

    from skfem_granular.simulation.folder import LOCK_NAME

    before = _hashes(copy_of)
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (copy_of / LOCK_NAME).write_text(json.dumps(
            {"pid": holder.pid, "host": socket.gethostname(), "what": "study"}))
        assert main(["study", "faxen", "--out", str(copy_of)]) == 2
        assert only_error_line(capsys).startswith(
            f"skfem-granular: error: output folder {str(copy_of)!r}: in use by a running "
            f"study (pid {holder.pid} on ")
        assert main(["run", "single-particle", "--t-end", "2e-5", "--out", str(copy_of),
                     "--no-progress"]) == 2
        assert f"in use by a running study (pid {holder.pid} on " in only_error_line(capsys)
    finally:
        holder.kill()
        holder.wait()
    (copy_of / LOCK_NAME).unlink()
    for extra in ([], ["--overwrite"]):
        assert main(["run", "single-particle", "--t-end", "2e-5", "--out", str(copy_of),
                     "--no-progress", *extra]) == 2
        assert only_error_line(capsys) == (
            f"skfem-granular: error: output folder {str(copy_of)!r}: holds the output of the "
            "study 'faxen' (study.json); a run needs a folder of its own")
    assert _hashes(copy_of) == before
