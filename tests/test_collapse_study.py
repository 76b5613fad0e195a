"""The collapse study: runs of the loose/dense x dry/immersed matrix on an executor.

References: the records of one run are the same numbers whichever executor ran it (this
process, a local process pool, a Dask cluster: the runs are deterministic); a run read
back is not run again (its cost file counts one process); the summary is the sample mean
and standard deviation over the seeds (numpy); the run-out a record reports is the one
:func:`~skfem_granular.collapse.collapse_series` reads from the run's saved history; the
front is never faster than Ritter's inviscid dam break, ``(L - L0) / L0 <= 2 a t / tau_c``;
a run stopped at rest has its kinetic energy below ``stop_ratio`` of its peak.
"""

import json

import numpy as np
import pytest

from skfem_granular.collapse import collapse_series, column_scene, history_columns
from skfem_granular.studies import (
    CollapseRun,
    cached_packing,
    execute_collapse,
    plan_collapse,
    run_collapse_study,
)

#: two dry 30-grain collapses of 0.5 tau_c (DEM only: about a second each)
DRY = dict(t_end_tau=0.5, checkpoint_every=50)


@pytest.fixture(scope="module")
def packings(tmp_path_factory):
    """The columns, prepared once for the module (dense, seeds 0 and 1)."""
    where = tmp_path_factory.mktemp("packings")
    for seed in (0, 1):
        cached_packing(30, "dense", seed, where)
    return where


def test_cached_packing_of_other_grains_is_named_by_them(packings, tmp_path):
    """Grains of another size and stiffness are a file of their own, the column that
    prepare_column gives for them bit for bit; the defaults keep the plain name."""
    from skfem_granular.packing import prepare_column

    assert {"dense_a0.8_n30_seed0.npz", "dense_a0.8_n30_seed1.npz"} <= {
        p.name for p in packings.glob("*.npz")}
    pk = cached_packing(30, "dense", 0, tmp_path, d_mean=1.5e-3, E=1.5e6)
    assert [p.name for p in tmp_path.glob("*.npz")] == ["dense_a0.8_n30_seed0_d1.5mm_E1.5e+06.npz"]
    ref = prepare_column(30, 0.8, "dense", seed=0, d_mean=1.5e-3, E=1.5e6)
    assert (pk.d_mean, pk.E) == (1.5e-3, 1.5e6) and pk == ref
    assert all(np.array_equal(a, b) for a, b in zip(pk.outlines, ref.outlines, strict=True))
    again = cached_packing(30, "dense", 0, tmp_path, d_mean=1.5e-3, E=1.5e6)  # read back
    assert again == pk and len(list(tmp_path.glob("*.npz"))) == 1


@pytest.fixture(scope="module")
def inline(packings, tmp_path_factory):
    runs = plan_collapse(30, states=["dense"], media=["dry"], seeds=[0, 1], **DRY)
    return runs, run_collapse_study(runs, tmp_path_factory.mktemp("inline"), packings=packings)


def _numbers(rec):
    """A record without its cost (CPU, wall, memory: the machine's, not the run's)."""
    return {k: v for k, v in rec.items()
            if k not in ("cpu_s", "wall_s", "phases_s", "peak_mb", "processes")}


def test_plan_is_the_matrix_with_one_folder_per_run():
    runs = plan_collapse(30, cores=[0.7, 0.9], seeds=[0, 1])
    assert len(runs) == 2 * 2 * (1 + 2)  # seeds x states x (dry + two core ratios)
    keys = [r.key for r in runs]
    assert len(set(keys)) == len(keys)
    assert keys[:4] == ["dense_dry_s0", "dense_immersed_core0.7_s0",
                        "dense_immersed_core0.9_s0", "loose_dry_s0"]
    assert all(r.core_ratio == 1.0 for r in runs if r.medium == "dry")
    other = plan_collapse(30, media=["immersed"], cores=[0.95], seeds=[1],
                          rolling_friction=0.1, contact_stiffness=1e7)
    assert [r.key for r in other] == ["dense_immersed_core0.95_s1_mur0.1_E1e+07",
                                      "loose_immersed_core0.95_s1_mur0.1_E1e+07"]


def test_records_summary_and_measures_against_the_saved_history(inline, packings):
    runs, study = inline
    assert not study.stopped and not study.failed
    assert [r["run"] for r in study.records] == [r.key for r in runs]
    for run, rec in zip(runs, study.records, strict=True):
        pk = cached_packing(30, "dense", run.seed, packings)
        s = collapse_series(history_columns(study.out_dir / run.key / "history.csv"), pk,
                            column_scene(pk, fluid=False).domain)
        assert rec["final_runout_gap_front"] == s["runout"][-1]
        assert np.array_equal(rec["series"]["runout"], s["runout"])
        # the run ends on its first row (1 ms apart) at or after 0.5 tau_c
        tau = np.sqrt(pk.height / 9.81)
        assert 0.5 <= rec["t_end_over_tau"] < 0.5 + 1e-3 / tau
        # Ritter: the front of an inviscid column released from rest moves at 2 sqrt(g H0),
        # (L - L0) / L0 <= 2 a t / tau_c, up to the outlines' overlap at rest (as in
        # test_collapse: 0.05 d_max)
        ritter = 2 * pk.aspect * np.asarray(rec["series"]["t_over_tau"])
        slack = 0.05 * pk.d_max / pk.width
        assert np.all(np.asarray(rec["series"]["runout"]) <= ritter + slack)
        assert rec["processes"] == 1 and rec["cpu_s"] > 0
    (row,) = study.summary
    values = [r["final_runout_mass_front"] for r in study.records]
    assert row["seeds"] == [0, 1]
    assert row["final_runout_mass_front"]["mean"] == pytest.approx(np.mean(values), rel=1e-14)
    assert row["final_runout_mass_front"]["std"] == pytest.approx(np.std(values, ddof=1),
                                                                  rel=1e-12)
    on_disk = json.loads((study.out_dir / "records.json").read_text())
    assert [_numbers(r) for r in on_disk["records"]] == [_numbers(r) for r in study.records]


def test_a_finished_run_is_read_back_not_run_again(inline, packings):
    runs, study = inline
    again = run_collapse_study(runs, study.out_dir, packings=packings)
    assert [_numbers(r) for r in again.records] == [_numbers(r) for r in study.records]
    assert all(r["processes"] == 1 for r in again.records)  # nobody stepped them again


def test_process_pool_gives_the_same_records(inline, packings, tmp_path):
    runs, study = inline
    pooled = run_collapse_study(runs, tmp_path, packings=packings, workers=2)
    assert [_numbers(r) for r in pooled.records] == [_numbers(r) for r in study.records]


@pytest.mark.filterwarnings("ignore")
def test_dask_executor_gives_the_same_records(inline, packings, tmp_path):
    distributed = pytest.importorskip("distributed")
    runs, study = inline
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        res = run_collapse_study(runs, tmp_path, packings=packings,
                                 executor=client.get_executor())
    assert [_numbers(r) for r in res.records] == [_numbers(r) for r in study.records]


def test_to_rest_stops_below_the_energy_ratio(packings, tmp_path):
    run = CollapseRun(30, "dense", "dry", seed=0, t_end_tau=10.0, to_rest=True,
                      stop_ratio=0.3, t_min_tau=0.5)
    rec = execute_collapse(run, tmp_path, packings)
    assert rec["status"] == "completed" and rec["at_rest"]
    assert rec["energy_ratio"] < 0.3
    rest = json.loads((tmp_path / run.key / "rest.json").read_text())
    assert 0.5 <= rest["t_over_tau"] < 10.0 and rest["energy_ratio"] == rec["energy_ratio"]


def test_immersed_run_records_its_mesh(packings, tmp_path):
    """Two coupled steps of the dense column in water: DOFs and the run's cost counted."""
    pk = cached_packing(30, "dense", 0, packings)
    tau = np.sqrt(pk.height / 9.81)
    run = CollapseRun(30, "dense", "immersed", seed=0, core_ratio=0.8,
                      t_end_tau=2 * 2e-4 / tau)
    rec = execute_collapse(run, tmp_path, packings)
    assert rec["status"] == "completed" and rec["steps"] == 2 and rec["remeshes"] == 0
    # one mesh throughout: its unknowns are 2 per P2 node plus 1 per vertex (Taylor-Hood),
    # counted here from the last saved frame
    import meshio

    frame = sorted((tmp_path / run.key).glob("flow_*.vtu"))[-1]
    m = meshio.read(frame)
    vertices = np.unique(m.cells_dict["triangle6"][:, :3]).size
    assert rec["dofs_max"] == rec["dofs_mean"] == 2 * len(m.points) + vertices
    # the poorest mesh the steps ended on: the grains settle from rest, so the gaps only
    # shrink over these two steps and the last step's mesh (the last frame) is the poorest;
    # its angles and its areas against the first frame's (the mesh as built, same
    # triangles: no remesh) measured here from the frames' points
    from meshing.quality import signed_areas, triangle_stats

    m0 = meshio.read(sorted((tmp_path / run.key).glob("flow_*.vtu"))[0])
    t = m.cells_dict["triangle6"][:, :3].T.astype(np.int64)
    assert np.array_equal(t, m0.cells_dict["triangle6"][:, :3].T)
    p0, p1 = m0.points[:, :2].T.copy(), m.points[:, :2].T.copy()
    assert rec["mesh_steps_checked"] == 2 and rec["retries"] == 0
    assert rec["mesh_min_angle"] == pytest.approx(triangle_stats(p1, t).min_angle, rel=1e-12)
    ratio = (signed_areas(p1, t) / signed_areas(p0, t)).min()
    assert rec["mesh_min_area_ratio"] == pytest.approx(ratio, rel=1e-12)
    assert ratio < 1.0  # the grains have moved: the check is not of the mesh as built


@pytest.mark.parametrize("change, message", [
    (dict(state="medium"), "state = 'medium': must be one of dense, loose"),
    (dict(medium="wet"), "medium = 'wet': must be one of dry, immersed"),
    (dict(medium="immersed", core_ratio=1.2), "core_ratio = 1.2: must be in (0, 1]"),
    (dict(core_ratio=0.8), "core_ratio = 0.8: a dry run has no fluid outline"),
    (dict(n=1), "n = 1: must be an integer >= 2"),
    (dict(seed=-1), "seed = -1: must be an integer >= 0"),
    (dict(t_end_tau=0.0), "t_end_tau = 0.0: must be finite and > 0"),
    (dict(to_rest=True, stop_ratio=1.5), "stop_ratio = 1.5: must be in (0, 1)"),
    (dict(to_rest=True, t_min_tau=9.0), "t_min_tau = 9.0: must satisfy"),
    (dict(rolling_friction=-0.1), "rolling_friction = -0.1: must be finite and >= 0"),
    (dict(contact_stiffness=0.0), "contact_stiffness = 0.0: must be finite and > 0"),
])
def test_bad_run_one_line(change, message):
    spec = dict(n=30, state="dense", medium="dry") | change
    with pytest.raises(ValueError) as err:
        CollapseRun(**spec)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_bad_study_input_one_line(tmp_path):
    run = CollapseRun(30, "dense", "dry")
    with pytest.raises(ValueError, match=r"workers = 0: must be an integer >= 1"):
        run_collapse_study([run], tmp_path, workers=0)
    with pytest.raises(ValueError, match="dense_dry_s0 given more than once"):
        run_collapse_study([run, run], tmp_path)
    with pytest.raises(TypeError, match="runs: dict given; each must be a CollapseRun"):
        run_collapse_study([{"n": 30}], tmp_path)


def test_cli_runs_the_matrix_and_prints_the_spread(tmp_path, capsys):
    from skfem_granular.cli import main

    argv = ["collapse", "30", "--out", str(tmp_path), "--states", "dense", "--media", "dry",
            "--seeds", "0", "1", "--tau", "0.5"]
    assert main(argv) == 0
    out = capsys.readouterr().out.splitlines()
    records = json.loads((tmp_path / "records.json").read_text())["records"]
    values = [r["final_runout_mass_front"] for r in records]
    assert [line.split(":")[0] for line in out[:2]] == ["dense_dry_s0", "dense_dry_s1"]
    assert out[2] == (f"dense dry: run-out {np.mean(values):.3f} +- "
                      f"{np.std(values, ddof=1):.3f} ({min(values):.3f} - {max(values):.3f}) "
                      "over seeds [0, 1]")


@pytest.mark.parametrize("argv, text", [
    (["--states", "medium"], "state = 'medium': must be one of dense, loose"),
    (["--workers", "0"], "--workers = 0: must be an integer in [1, 1024]"),
    (["--cores", "1.5", "--media", "immersed"], "--cores = 1.5: must be a finite number in (0, 1]"),
    (["--to-rest", "--t-min", "25"], "--t-min = 25.0: must be a finite number in [0, 20)"),
])
def test_cli_bad_input_one_line_exit_2(argv, text, tmp_path, capsys):
    from skfem_granular.cli import main

    assert main(["collapse", "30", "--out", str(tmp_path)] + argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and text in err[0]


def test_a_run_cut_off_continues_to_the_same_record(packings, tmp_path):
    """A run broken off after 12 of its steps (checkpoints every 5) and started again
    gives the record of the run that never stopped (resumed bit for bit)."""
    from dataclasses import replace

    from skfem_granular.simulation import Simulation

    run = CollapseRun(30, "dense", "dry", seed=1, t_end_tau=0.8, checkpoint_every=5)
    whole = execute_collapse(run, tmp_path / "whole", packings)
    pk = cached_packing(30, "dense", 1, packings)
    folder = tmp_path / "cut" / run.key
    scene = column_scene(pk, fluid=False, t_end=run.t_end_tau * np.sqrt(pk.height / 9.81),
                         name=folder.name, output_dir=str(folder), vtu_every=run.vtu_every)
    sim = Simulation(replace(scene, checkpoint_every=5))
    steps = sim.evolve(progress=False)
    for _ in range(12):
        next(steps)
    steps.close()
    assert json.loads((folder / "summary.json").read_text())["status"] == "closed"
    cut = execute_collapse(run, tmp_path / "cut", packings)
    assert cut["processes"] == 1  # the cut run was not a study's: only the one continuing it books
    assert _numbers(cut) == _numbers(whole)


def test_a_failed_run_does_not_lose_the_others(packings, tmp_path):
    """A column that cannot be prepared (deposition limit 1 ms) fails, in this process and
    in a pool; the other run's record is kept."""
    good = CollapseRun(30, "dense", "dry", seed=0, **DRY)
    bad = CollapseRun(30, "loose", "dry", seed=5, packing_t_max=1e-3, **DRY)
    for workers in (1, 2):
        study = run_collapse_study([bad, good], tmp_path / f"w{workers}", packings=packings,
                                   workers=workers)
        assert [r["run"] for r in study.records] == [good.key]
        assert list(study.failed) == [bad.key] and "t_max" in study.failed[bad.key]


def test_records_of_two_studies_in_one_folder_are_merged(packings, tmp_path):
    a = CollapseRun(30, "dense", "dry", seed=0, **DRY)
    b = CollapseRun(30, "dense", "dry", seed=1, **DRY)
    run_collapse_study([a], tmp_path, packings=packings)
    run_collapse_study([b], tmp_path, packings=packings)
    on_disk = json.loads((tmp_path / "records.json").read_text())
    assert [r["run"] for r in on_disk["records"]] == [a.key, b.key]
    assert on_disk["summary"][0]["seeds"] == [0, 1]


def test_a_folder_of_other_settings_is_refused(packings, tmp_path):
    run = CollapseRun(30, "dense", "dry", seed=0, **DRY)
    run_collapse_study([run], tmp_path, packings=packings)
    longer = CollapseRun(30, "dense", "dry", seed=0, t_end_tau=1.0)
    with pytest.raises(ValueError) as err:
        run_collapse_study([longer], tmp_path, packings=packings)
    msg = str(err.value)
    assert "t_end_tau = 0.5" in msg and "(asked: t_end_tau = 1.0)" in msg and "\n" not in msg


def test_numpy_numbers_become_plain_ones():
    (run,) = plan_collapse(np.int64(30), states=["dense"], media=["dry"], seeds=np.arange(1))
    assert type(run.n) is int and type(run.seed) is int and type(run.aspect) is float
    json.dumps(run.__dict__)


@pytest.mark.parametrize("axes, message", [
    (dict(seeds=0), "seeds = 0: must be a list of values"),
    (dict(states="dense"), "states = 'dense': must be a list of values"),
    (dict(cores=[]), "cores = []: must name at least one value"),
    (dict(seeds=[1, 1]), "seeds = [1, 1]: each value once"),
    (dict(cores=["0.8"]), "core_ratio = '0.8': must be a number"),
])
def test_bad_plan_one_line(axes, message):
    with pytest.raises(ValueError) as err:
        plan_collapse(30, **axes)
    assert message in str(err.value)


def test_failed_writes_keep_the_earlier_records(tmp_path, monkeypatch):
    """records.json, run.json and a packing file whose write fails halfway (a full disk):
    the earlier file stays byte for byte (or none is made) and no temporary file is left."""
    from pathlib import Path

    from helpers import fail_midway, partial_names

    from skfem_granular.studies import check_folder, merge_records
    from skfem_granular.studies.collapse import SUMMARY_KEYS

    def record(seed):
        return {"run": f"dense_dry_s{seed}", "state": "dense", "medium": "dry",
                "core_ratio": 1.0, "seed": seed, **{k: 0.5 + seed for k in SUMMARY_KEYS}}

    path = tmp_path / "records.json"
    merge_records(path, [record(0)])
    before = path.read_bytes()
    with monkeypatch.context() as m:
        fail_midway(m, Path, "write_text", lambda self, *a: self, data=b'{"records": [')
        with pytest.raises(OSError, match="No space left"):
            merge_records(path, [record(1)])
        with pytest.raises(OSError, match="No space left"):
            check_folder(CollapseRun(30, "dense", "dry"), tmp_path / "dense_dry_s0")
    assert path.read_bytes() == before
    assert not (tmp_path / "dense_dry_s0" / "run.json").exists()
    assert partial_names(tmp_path) == [] and partial_names(tmp_path / "dense_dry_s0") == []
    assert [r["seed"] for r in merge_records(path, [record(1)])] == [0, 1]
