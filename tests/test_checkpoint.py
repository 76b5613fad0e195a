"""Checkpoints: a resumed run reproduces an uninterrupted one bit for bit."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from skfem_granular.scene import Scene, TimeSpec, bundled
from skfem_granular.simulation import Simulation

SCENES = bundled("single_particle").parent  # the bundled scenes (skfem_granular/scene/library)
COLUMNS = ("t", "dt", "iterations", "x", "y", "angle", "vx", "vy", "omega", "Fx", "Fy", "torque")


def _with(scene, t_end, every=0):
    return replace(scene, time=TimeSpec(t_end=t_end, dt=scene.time.dt, dem_dt=scene.time.dem_dt),
                   checkpoint_every=every, vtu_every=4)


def _assert_same(h1, h2):
    assert len(h1) == len(h2)
    for c in COLUMNS:
        assert np.array_equal(getattr(h1, c), getattr(h2, c)), c


def _check_resume(scene, n_total, n_first, tmp_path):
    dt = scene.time.dt
    full = Simulation(_with(scene, n_total * dt, every=n_first), output_dir=tmp_path / "full")
    h_full = full.run(progress=False).history
    part = Simulation(_with(scene, n_first * dt, every=n_first), output_dir=tmp_path / "part")
    part.run(progress=False)
    resumed = Simulation.resume(tmp_path / "part", t_end=n_total * dt)
    h_res = resumed.run(progress=False).history
    _assert_same(h_full, h_res)
    return full, resumed


def test_resume_single_particle_bit_for_bit(tmp_path):
    scene = Scene.from_toml(SCENES / "single_particle.toml")
    full, resumed = _check_resume(scene, 20, 10, tmp_path)
    assert np.array_equal(full.last_good.x, resumed.last_good.x)  # fluid velocity and pressure
    assert np.array_equal(full.last_good.u_prev, resumed.last_good.u_prev)  # BDF2 history
    # the series continues: every frame time of the full run is in the resumed series
    # (which also has the frame the first part wrote at its end)
    from skfem_granular.viz import read_pvd

    t_full = {t for t, _ in read_pvd(tmp_path / "full" / "flow.pvd")}
    t_part = {t for t, _ in read_pvd(tmp_path / "part" / "flow.pvd")}
    assert t_full <= t_part and len(t_part) == len(t_full) + 1


@pytest.mark.parametrize("motion", ["fixed", "ale"])
def test_resume_with_contacts_and_remeshing_bit_for_bit(tmp_path, motion):
    data = {"domain": {"box": [0.0, 0.0, 6e-3, 4e-3]},
            "fluid": {"density": 1000.0, "viscosity": 1e-3},
            "grid": {"nx": 2, "ny": 1, "sides": 6, "radius": 0.5e-3, "spacing": 1.1e-3,
                     "origin": [2.4e-3, 0.437e-3], "density": 2650.0, "core_ratio": 0.8},
            "mesh": {"kind": "group", "delta_l": 0.2e-3},
            "time": {"t_end": 3e-3, "dt": 2e-4},
            "coupling": {"remesh_fraction": 0.005, "mesh_motion": motion,
                         "remesh_travel": 0.01}}
    scene = Scene.from_dict(data, name="floor")
    full, resumed = _check_resume(scene, 14, 7, tmp_path)
    assert resumed.remeshes >= 1 and resumed.contacts_active
    assert np.array_equal(full.last_good.x, resumed.last_good.x)


def test_resume_moving_mesh_bit_for_bit(tmp_path):
    """ALE runs carry the mesh vertices in the state: stored with no change to the format."""
    scene = replace(Scene.from_toml(SCENES / "single_particle.toml"), mesh_motion="ale")
    full, resumed = _check_resume(scene, 14, 7, tmp_path)
    assert resumed.last_good.nodes_n is not None
    assert np.array_equal(full.last_good.nodes_n, resumed.last_good.nodes_n)
    assert np.array_equal(full.last_good.x, resumed.last_good.x)
    assert ((tmp_path / "full" / "history.csv").read_text()
            == (tmp_path / "part" / "history.csv").read_text())


def test_resume_dry_scene_bit_for_bit(tmp_path):
    scene = replace(Scene.from_toml(SCENES / "single_particle.toml"), fluid=None)
    _check_resume(scene, 12, 6, tmp_path)


def test_resume_errors(tmp_path):
    with pytest.raises(ValueError, match="no checkpoint.npz"):
        Simulation.resume(tmp_path)
    (tmp_path / "checkpoint.npz").write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="not a readable file of this format"):
        Simulation.resume(tmp_path)


def test_pickle_checkpoint_of_earlier_versions_is_refused_unread(tmp_path):
    """A checkpoint.pkl is never unpickled: this one would create a file if it were."""
    import pickle  # noqa: F401 -- only here, to craft the hostile file the package refuses

    marker = tmp_path / "pwned"

    class Payload:
        def __reduce__(self):
            return (open, (str(marker), "w"))

    (tmp_path / "checkpoint.pkl").write_bytes(pickle.dumps(Payload()))
    with pytest.raises(ValueError, match="checkpoint.pkl'?: a pickle file, not loaded"):
        Simulation.resume(tmp_path)
    assert not marker.exists()


def test_cli_resume(tmp_path, capsys):
    from skfem_granular.cli import main

    toml = (SCENES / "single_particle.toml").read_text().replace(
        "vtu_every = 10", "vtu_every = 5\ncheckpoint_every = 5")
    scene = tmp_path / "sp.toml"
    scene.write_text(toml)
    out = tmp_path / "out"
    assert main(["run", str(scene), "--out", str(out), "--t-end", "1e-4", "--no-progress"]) == 0
    assert main(["run", "--resume", str(out), "--t-end", "2e-4", "--no-progress"]) == 0
    table = np.loadtxt(out / "history.csv", delimiter=",", skiprows=1)
    assert table.shape[0] == 20 and table[-1, 0] == pytest.approx(2e-4)
    capsys.readouterr()
    assert main(["run", "--resume", str(tmp_path / "nothing")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no checkpoint.npz" in err[0]


def test_resume_adaptive_run_bit_for_bit(tmp_path):
    """Adaptive steps: the proposed next step and the derivative histories are in the
    checkpoint, so the resumed run takes the same steps."""
    scene = Scene.from_toml(SCENES / "single_particle.toml")
    scene = replace(scene, time=replace(scene.time, adaptive=True, tol=1e-4))
    full = Simulation(replace(scene, time=replace(scene.time, t_end=2e-4), checkpoint_every=8),
                      output_dir=tmp_path / "full")
    h_full = full.run(progress=False).history
    part = Simulation(replace(scene, time=replace(scene.time, t_end=2e-4), checkpoint_every=8),
                      output_dir=tmp_path / "part")
    part.run(progress=False)  # writes checkpoints at 8, 16, ... steps; resume the last
    from skfem_granular.simulation import checkpoint

    k = checkpoint.load(tmp_path / "part")["k"]
    assert 0 < k < len(h_full)  # the resumed run takes steps of its own (measured 16 of 23)
    resumed = Simulation.resume(tmp_path / "part", t_end=2e-4)
    assert resumed.scene.time.adaptive and resumed.scene.time.tol == 1e-4
    h_res = resumed.run(progress=False).history
    _assert_same(h_full, h_res)
    assert np.array_equal(h_full.error, h_res.error, equal_nan=True)
    assert np.isfinite(h_full.error).any() and np.nanmax(h_full.error) <= 1e-4


# ---------------------------------------------------------------- the file format
def _part_run(tmp_path, steps=6, every=3):
    scene = Scene.from_toml(SCENES / "single_particle.toml")
    sim = Simulation(_with(scene, steps * scene.time.dt, every=every), output_dir=tmp_path)
    sim.run(progress=False)
    return sim


def test_checkpoint_is_plain_data(tmp_path):
    """numpy reads the arrays without pickle; the header is JSON with format and version."""
    import json
    import zipfile

    from skfem_granular.simulation import checkpoint

    sim = _part_run(tmp_path)
    path = tmp_path / "checkpoint.npz"
    with np.load(path, allow_pickle=False) as npz:
        names = set(npz.files)
        u = npz["stepper.state.u_n"]
        assert {npz[n].dtype.name for n in names if n != "header.json"} <= {
            "float64", "int64", "int32", "bool"}
    assert np.array_equal(u, sim.last_good.u_n)
    with zipfile.ZipFile(path) as zf:
        header = json.loads(zf.read("header.json"))
    assert header["format"] == "skfem-granular checkpoint" and header["version"] == 4
    assert {"stepper.mesh.mesh.doflocs", "stepper.mesh.mesh.t", "dem.contact_keys",
            "history.last.particle.vy"} <= names
    assert not any(n.startswith("history.") and "last" not in n for n in names)  # in the csv
    data = checkpoint.load(tmp_path)
    assert data["k"] == 6 and len(data["history"]) == 6
    for mine, back in zip(sim.history.rows, data["history"], strict=True):  # read back exactly
        assert mine.keys() == back.keys()
        for c, v in mine.items():
            assert type(back[c]) is (np.ndarray if isinstance(v, np.ndarray) else
                                     int if isinstance(v, (int, np.integer)) else float), c
            assert np.array_equal(v, back[c], equal_nan=True), c
    back = data["scene"]  # rebuilt through the validating constructors
    assert replace(back, particles=sim.scene.particles) == sim.scene
    for p, q in zip(back.particles, sim.scene.particles, strict=True):
        assert np.array_equal(p.polygon.vertices, q.polygon.vertices)
        assert (p.density, p.velocity, p.core_ratio) == (q.density, q.velocity, q.core_ratio)
    mesh = data["stepper"]["mesh"]
    assert np.array_equal(mesh.mesh.t, sim.mesh.t) and mesh.mesh.t.dtype == sim.mesh.t.dtype
    assert sorted(mesh.mesh.boundaries) == sorted(sim.mesh.boundaries)
    assert mesh.recipe.kind == "graded" and mesh.recipe.options == sim.stepper.meshed.recipe.options


def test_generic_format_round_trips_new_dataclass_fields(tmp_path):
    """A field added to a stored dataclass later (CoupledState, say) round-trips with no
    change to the format's code: a made-up state with new fields of every kind."""
    from dataclasses import dataclass, field, fields

    from skfem_granular.coupled.state import CoupledState
    from skfem_granular.io import plain
    from skfem_granular.simulation import checkpoint

    @dataclass(frozen=True)
    class GrownState(CoupledState):  # the moving mesh's extra fields, made up
        mesh_velocity: np.ndarray | None = None
        node_ids: np.ndarray | None = None
        flags: np.ndarray | None = None
        ale_steps: int = 0
        last_move: float | None = None
        residual: float = float("nan")  # NaN by default: allowed NaN
        moves: tuple = ()
        extra: dict = field(default_factory=dict)

    reg = plain.Registry(dataclasses=[GrownState, *checkpoint.REGISTRY_DATACLASSES],
                         custom=checkpoint.REGISTRY_CUSTOM)
    sim = _part_run(tmp_path)
    base = sim.last_good
    grown = GrownState(**{f.name: getattr(base, f.name) for f in fields(CoupledState)},
                       mesh_velocity=np.linspace(0, 1, 7).reshape(7, 1),
                       node_ids=np.arange(5, dtype=np.int32), flags=np.array([True, False]),
                       ale_steps=3, last_move=2.5e-6,
                       moves=(np.zeros((2, 0)), "remesh", None),
                       extra={"k": [1, 2.0, None], "s": "x", "np": np.float64(0.1)})
    value = {"state": grown, "mesh": sim.stepper.meshed}
    node, arrays = plain.encode(value, reg)
    plain.write(tmp_path / "grown.npz", {"content": node}, arrays)
    header, arrays2 = plain.read(tmp_path / "grown.npz")
    back = plain.decode(header["content"], arrays2, reg)
    s2 = back["state"]
    assert type(s2) is GrownState
    for f in fields(GrownState):
        a, b = getattr(grown, f.name), getattr(s2, f.name)
        if isinstance(a, np.ndarray):
            assert a.dtype == b.dtype and np.array_equal(a, b, equal_nan=True), f.name
        elif f.name == "moves":
            assert b[1:] == a[1:] and b[0].shape == (2, 0)
        elif isinstance(a, float) and np.isnan(a):
            assert np.isnan(b)
        else:
            assert a == b and type(a) is type(b), f.name
    assert type(s2.extra["np"]) is np.float64
    assert np.array_equal(back["mesh"].mesh.p, sim.stepper.meshed.mesh.p)  # the mesh as built


def test_history_file_grows_and_equals_the_whole_table(tmp_path):
    """The live history.csv is the text to_csv writes, at every flush and at the end."""
    from skfem_granular.io import read_csv

    sim = _part_run(tmp_path, steps=7, every=0)
    live = (tmp_path / "history.csv").read_text()
    sim.history.to_csv(tmp_path / "whole.csv")
    assert live == (tmp_path / "whole.csv").read_text()
    head = ",".join(sim.history.wide_header())
    np.savetxt(tmp_path / "np.csv", np.column_stack(
        [getattr(sim.history, c) for c in sim.history.STEP_COLUMNS]
        + [getattr(sim.history, c)[:, 0] for c in sim.history.PARTICLE_COLUMNS]),
        delimiter=",", header=head, comments="", fmt="%.17g")
    assert live == (tmp_path / "np.csv").read_text()  # the format history.csv always had
    cols = read_csv(tmp_path / "history.csv")
    assert np.array_equal(cols["vy_0"], sim.history.vy[:, 0])
    # a torn last line (a kill inside an append) is left out by the reader
    (tmp_path / "torn.csv").write_text(live + "1e-05,1e-0")
    assert read_csv(tmp_path / "torn.csv")["t"].shape == (7,)


def test_resumed_history_file_drops_rows_after_the_checkpoint(tmp_path):
    """Rows a killed run wrote after its last checkpoint are replaced by the resumed ones."""
    scene = Scene.from_toml(SCENES / "single_particle.toml")
    dt = scene.time.dt
    full = Simulation(_with(scene, 10 * dt, every=4), output_dir=tmp_path / "full")
    full.run(progress=False)
    part = Simulation(_with(scene, 6 * dt, every=4), output_dir=tmp_path / "part")
    part.run(progress=False)  # checkpoint at 4, history to 6
    assert len((tmp_path / "part" / "history.csv").read_text().splitlines()) == 7
    (tmp_path / "part" / ".partial-flow_00009-x.vtu").write_text("half a file")
    Simulation.resume(tmp_path / "part", t_end=10 * dt).run(progress=False)
    assert ((tmp_path / "part" / "history.csv").read_text()
            == (tmp_path / "full" / "history.csv").read_text())
    assert not list((tmp_path / "part").glob(".partial-*"))  # left-overs cleaned up


def test_moving_mesh_checkpoint_at_any_step_resumes_bit_for_bit(tmp_path):
    """A checkpoint at a step the uninterrupted run does not checkpoint at (as SIGTERM writes
    one): the resumed ALE run rebuilds the factorisation where the writer made it, so it
    equals the uninterrupted run (before: refactorising on the moved mesh changed the
    chord iterates at round-off, the angle at 1e-3 of its 1e-20 size)."""
    from helpers import resumed_between_checkpoints

    base = Scene.from_toml(SCENES / "single_particle.toml")
    sc = replace(base, time=replace(base.time, t_end=3e-4), mesh_motion="ale")
    ref, res = resumed_between_checkpoints(sc, tmp_path, 13)
    for c in ("vy", "angle", "omega", "Fy", "torque"):
        assert np.array_equal(getattr(ref, c), getattr(res, c)), c


@pytest.mark.parametrize("rule", ["rate", "amortised"])
def test_checkpoint_holding_a_newton_jacobian_resumes_bit_for_bit(tmp_path, monkeypatch, rule):
    """The corrector refreshes to a Newton Jacobian when the chord stalls (forced here: at
    least three iterations, and a refresh after the second, or whenever two steps have
    taken two iterations each beyond one); a checkpoint taken while one is held records the
    state it was formed at and what it has cost so far (the amortised rule's ledger), and the
    resumed run rebuilds the same one and refreshes where the uninterrupted run did."""
    from contextlib import closing

    import skfem_granular.coupled.monolithic as monolithic
    import skfem_granular.fluid.newton as newton
    from skfem_granular.simulation import checkpoint

    converged = monolithic.chord_converged
    monkeypatch.setattr(newton, "STALL_RULE", rule)
    monkeypatch.setattr(newton, "STALL_RATE", 0.0)
    monkeypatch.setattr(newton, "FRESH_ITERATIONS", 1)
    monkeypatch.setattr(newton, "REFRESH_ITERATIONS", 4.0)
    monkeypatch.setattr(monolithic, "chord_converged",
                        lambda dn, prev, it, tol: it >= 3 and converged(dn, prev, it, tol))
    base = Scene.from_toml(SCENES / "single_particle.toml")
    sc = replace(base, time=replace(base.time, t_end=3e-4), mesh_motion="ale")
    run = Simulation(sc, output_dir=tmp_path / "ref").run(progress=False)
    assert run.summary["jacobian_refreshes"] > 0
    sim = Simulation(sc, output_dir=tmp_path / "part")
    with closing(sim.evolve()) as steps:
        for k, _ in enumerate(steps, start=1):
            if k == 13:
                assert sim.stepper.coupling.factorized_on[2] is not None  # a Jacobian held
                if rule == "amortised":  # and part of its price paid
                    assert sim.stepper.coupling.factors.extra_iterations > 0
                checkpoint.save(sim, k, None)
                break
    res = Simulation.resume(tmp_path / "part").run(progress=False)
    for c in ("vy", "angle", "omega", "Fy", "torque"):
        assert np.array_equal(getattr(run.history, c), getattr(res.history, c)), c
    assert res.summary["jacobian_refreshes"] == run.summary["jacobian_refreshes"]
    assert res.summary["factorizations"] == run.summary["factorizations"]


def test_same_content_same_bytes(tmp_path, monkeypatch):
    """A plain-data file is a function of its content: written in two different seconds
    (the zip members were dated by the clock), the bytes are the same."""
    import time as _time

    from skfem_granular.io import plain

    node, arrays = plain.encode({"a": np.arange(5.0), "b": "x"}, plain.Registry())
    plain.write(tmp_path / "1.npz", {"content": node}, arrays)
    later = _time.time() + 3.0
    monkeypatch.setattr(_time, "time", lambda: later)
    monkeypatch.setattr(_time, "localtime", lambda t=None: _time.gmtime(later))
    plain.write(tmp_path / "2.npz", {"content": node}, arrays)
    assert (tmp_path / "1.npz").read_bytes() == (tmp_path / "2.npz").read_bytes()
    header, back = plain.read(tmp_path / "2.npz")
    assert np.array_equal(plain.decode(header["content"], back, plain.Registry())["a"],
                          np.arange(5.0))


# ---------------------------------------------------------------- the history in history.csv
def _as_version_3(directory):
    """Rewrite the checkpoint in ``directory`` as version 3 wrote it: the whole history inside."""
    from skfem_granular.io import History, plain
    from skfem_granular.simulation import checkpoint

    data = checkpoint.load(directory)
    rows, K = data["history"], len(data["scene"].particles)
    step = {c: np.array([r[c] for r in rows], dtype=np.int64 if c == "iterations" else float)
            for c in History.STEP_COLUMNS}
    part = {c: np.array([r[c] for r in rows]).reshape(len(rows), K)
            for c in History.PARTICLE_COLUMNS}
    content = {key: data[key] for key in ("scene", "k", "dem", "stepper", "frames")}
    content["history"] = {"particles": K, "step": step, "particle": part}
    node, arrays = plain.encode(content, checkpoint.REGISTRY)
    header = {"format": checkpoint.FORMAT, "version": 3, "written_by": "skfem-granular 0.x",
              "content": node}
    plain.write(Path(directory) / "checkpoint.npz", header, arrays)


def test_version_3_checkpoint_holding_the_history_is_still_read(tmp_path):
    """A checkpoint of the earlier format (the rows inside) resumes as before: from its own
    rows, whatever history.csv holds, to the uninterrupted run's history byte for byte."""
    scene = Scene.from_toml(SCENES / "single_particle.toml")
    dt = scene.time.dt
    Simulation(_with(scene, 10 * dt, every=4), output_dir=tmp_path / "full").run(progress=False)
    Simulation(_with(scene, 6 * dt, every=4), output_dir=tmp_path / "part").run(progress=False)
    _as_version_3(tmp_path / "part")
    (tmp_path / "part" / "history.csv").write_text("t\n0\n")  # not the rows: version 3 has them
    from skfem_granular.simulation import checkpoint

    data = checkpoint.load(tmp_path / "part")
    assert data["version"] == 3 and data["k"] == 4 and len(data["history"]) == 4
    Simulation.resume(tmp_path / "part", t_end=10 * dt).run(progress=False)
    assert ((tmp_path / "part" / "history.csv").read_bytes()
            == (tmp_path / "full" / "history.csv").read_bytes())
    with np.load(tmp_path / "part" / "checkpoint.npz", allow_pickle=False) as npz:  # rewritten
        assert "history.step.t" not in npz.files and "history.last.particle.vy" in npz.files


def _without_later_entries(directory):
    """Rewrite the checkpoint in ``directory`` as the version before mesh repairs wrote it:
    no ``Scene.mesh_repair``, ``CoupledState.p_prev``, travel poses or repair counters, no
    rolling resistance in the contact law."""
    import json
    import zipfile

    from skfem_granular.io import plain

    path = Path(directory) / "checkpoint.npz"
    with zipfile.ZipFile(path) as zf:
        header = json.loads(zf.read("header.json"))
    with np.load(path, allow_pickle=False) as npz:
        arrays = {n: npz[n] for n in npz.files if n != "header.json"}
    content = header["content"]["$dict"]
    content["scene"]["fields"].pop("mesh_repair")
    for name in ("mu_r", "eta_r"):
        content["scene"]["fields"]["contact_law"]["fields"].pop(name)
    stepper = content["stepper"]["$dict"]
    stepper["state"]["fields"].pop("p_prev")
    arrays.pop(stepper.pop("travel_poses")["$array"])
    counters = stepper["counters"]["$dict"]
    for k in [k for k in counters if k.startswith("repairs.")]:
        counters.pop(k)
    plain.write(path, header, arrays)


def test_checkpoint_written_before_later_fields_resumes_byte_for_byte(tmp_path):
    """A checkpoint without the entries added since (read at what that version did: no
    repair, no pressure history, the mesh graded where it was built) resumes to the
    uninterrupted run's history byte for byte."""
    scene = Scene.from_toml(SCENES / "single_particle.toml")
    dt = scene.time.dt
    Simulation(_with(scene, 10 * dt, every=4), output_dir=tmp_path / "full").run(progress=False)
    Simulation(_with(scene, 6 * dt, every=4), output_dir=tmp_path / "part").run(progress=False)
    _without_later_entries(tmp_path / "part")
    Simulation.resume(tmp_path / "part", t_end=10 * dt).run(progress=False)
    assert ((tmp_path / "part" / "history.csv").read_bytes()
            == (tmp_path / "full" / "history.csv").read_bytes())


def test_history_log_keeps_the_digest_of_the_bytes_it_wrote(tmp_path):
    """CSVLog.digest(n) is the SHA-256 of the file from its start to the end of row n (n the
    rows written or one fewer), however the rows came: with the header, one or more per flush,
    and when a resumed run's log opens with rows."""
    import hashlib

    from skfem_granular.io import CSVLog, History

    def prefix_sha(path, n):
        lines = path.read_bytes().split(b"\n")
        return hashlib.sha256(b"".join(x + b"\n" for x in lines[:n + 1])).hexdigest()

    h = History(3)
    path = tmp_path / "h.csv"
    log = CSVLog(h, path)
    assert log.digest(0) == prefix_sha(path, 0)
    rng = np.random.default_rng(1)
    for per_flush in (1, 3, 1, 2):
        for _ in range(per_flush):
            h.append(rng.random(), 1e-5, 2, error=np.nan, x=rng.standard_normal(3) * 1e-300,
                     vy=-rng.random(3), contacts=np.array([0.0, 1.0, -0.0]))
        log.flush()
        n = len(h)
        assert log.digest(n) == prefix_sha(path, n) and log.digest(n - 1) == prefix_sha(path, n - 1)
        with pytest.raises(ValueError, match="the digest is kept for"):
            log.digest(n - 2)
    log.close()
    again = CSVLog(h, tmp_path / "again.csv")  # a resumed run's file: the same bytes
    assert (tmp_path / "again.csv").read_bytes() == path.read_bytes()
    assert again.digest(len(h) - 1) == prefix_sha(path, len(h) - 1)
    again.close()


# ---------------------------------------------------------------- the ring of two checkpoints
HEAP = {"domain": {"box": [0.0, 0.0, 6e-3, 4e-3]},
        "grid": {"nx": 3, "ny": 2, "sides": 6, "radius": 0.5e-3, "spacing": 1.05e-3,
                 "origin": [1.9e-3, 0.45e-3], "density": 2650.0},
        "time": {"t_end": 1.0, "dt": 2e-4}, "effects": {"fluid": False}}


def _heap(steps, every=50):
    """Six hexagons settling into a heap on the floor with the DEM alone (9 contacts from
    step ~200 on): the cheapest scene whose checkpoints hold what a coupled run's do but the
    fluid (2000 steps in about 3 s)."""
    sc = Scene.from_dict(HEAP, name="dry-heap")
    return replace(sc, time=replace(sc.time, t_end=steps * sc.time.dt), checkpoint_every=every,
                   vtu_every=0)


def _k_of(path):
    """The step of the checkpoint file ``path`` (from its header only)."""
    from skfem_granular.io import plain

    header, _ = plain.read(path)
    return header["content"]["$dict"]["k"]


def _append_rows(folder, source, k, n):
    """Rows ``k + 1 .. k + n`` of ``source`` appended to ``folder``'s history, as a run killed
    after its checkpoint at ``k`` leaves them."""
    lines = (source / "history.csv").read_text().splitlines(keepends=True)
    with open(folder / "history.csv", "a") as f:
        f.write("".join(lines[k + 1:k + 1 + n]))


def test_checkpoints_of_a_long_run_keep_their_size_and_resume_byte_for_byte(tmp_path):
    """2010 steps, a checkpoint every 50: every checkpoint the same size within 1 % (measured
    15,616-15,717 B, the difference the contact springs; version 3's grew from 47,186 B at
    step 50 to 1,248,519 B at step 2000), the one before always kept as checkpoint.prev.npz,
    and the run resumed from its checkpoints at steps 500, 1250 and 2000 (copies of the
    folder made then, with rows written after the checkpoint as a killed run leaves them)
    gives the straight run's history.csv byte for byte and its summary numbers."""
    import json
    import shutil
    from contextlib import closing

    straight = tmp_path / "straight"
    sim = Simulation(_heap(2010), output_dir=straight)
    sizes = {}
    with closing(sim.evolve()) as steps:
        for k, _ in enumerate(steps, start=1):
            if k % 50 == 0:
                sizes[k] = (straight / "checkpoint.npz").stat().st_size
                if k > 50:
                    assert _k_of(straight / "checkpoint.prev.npz") == k - 50
                if k in (500, 1250, 2000):
                    shutil.copytree(straight, tmp_path / f"at{k}")
    assert len(sizes) == 40 and sim.dem.contact_count().sum() > 0
    assert max(sizes.values()) <= 1.01 * min(sizes.values()), sizes
    ref = json.loads((straight / "summary.json").read_text())
    for k in (500, 1250, 2000):
        folder = tmp_path / f"at{k}"
        _append_rows(folder, straight, k, 7)
        res = Simulation.resume(folder).run(progress=False)
        assert ((folder / "history.csv").read_bytes()
                == (straight / "history.csv").read_bytes()), k
        s = res.summary
        assert (s["steps"], s["t_end"], s["final"]) == (ref["steps"], ref["t_end"],
                                                        ref["final"]), k
        assert not s["warnings"]


def _all_columns_equal(h1, h2):
    assert len(h1) == len(h2)
    for c in h1.STEP_COLUMNS + h1.PARTICLE_COLUMNS:
        assert np.array_equal(getattr(h1, c), getattr(h2, c), equal_nan=True), c


def test_a_long_history_keeps_only_its_newest_rows_in_memory(tmp_path, monkeypatch):
    """Rows in history.csv keep their particle values in memory only while they are among
    the newest MEMORY_BYTES (here 20 rows of the six-hexagon heap): 300 steps with a
    checkpoint every 50 hold at most 20 such rows at every checkpoint, and their columns (read
    back from the file) and history.csv are the in-memory run's bit for bit; the run
    resumed from its checkpoint at step 200 (rows after it as a killed run leaves them)
    reads back at most 20 rows' values, keeps the file (cut, not rewritten: the same
    inode) and ends with the same history.csv and columns."""
    import os
    import shutil
    from contextlib import closing

    import skfem_granular.io.table as table

    whole = Simulation(_heap(300), output_dir=tmp_path / "whole").run(progress=False).history
    assert whole.dropped == 0
    monkeypatch.setattr(table, "MEMORY_BYTES", 20 * 8 * 6 * len(whole.PARTICLE_COLUMNS))
    lean_dir = tmp_path / "lean"
    sim = Simulation(_heap(300), output_dir=lean_dir)
    with closing(sim.evolve()) as steps:
        for k, _ in enumerate(steps, start=1):
            if k % 50 == 0:  # the file synced: rows not yet written stay in memory too
                assert sum("x" in r for r in sim.history.rows) <= 20, k
            if k == 200:
                shutil.copytree(lean_dir, tmp_path / "at200")
    lean = sim.result.history
    assert lean.dropped >= 280 and len(lean) == 300
    _all_columns_equal(whole, lean)
    text = (tmp_path / "whole" / "history.csv").read_bytes()
    assert (lean_dir / "history.csv").read_bytes() == text
    lean.to_csv(tmp_path / "again.csv")
    assert (tmp_path / "again.csv").read_bytes() == text

    folder = tmp_path / "at200"
    _append_rows(folder, lean_dir, 200, 7)
    inode = os.stat(folder / "history.csv").st_ino
    res = Simulation.resume(folder)
    assert res.history.dropped >= 180 and sum("x" in r for r in res.history.rows) <= 20
    resumed = res.run(progress=False).history
    assert os.stat(folder / "history.csv").st_ino == inode
    assert (folder / "history.csv").read_bytes() == text
    _all_columns_equal(whole, resumed)


def test_history_changed_before_the_checkpoints_is_refused_in_one_line(tmp_path, capsys):
    """A digit changed in a row before both checkpoints: resuming is refused with one line
    naming history.csv (exit 2), the folder unchanged. Changed in a row after the previous
    checkpoint: the newest is refused and the run resumes from the previous one, byte for
    byte the straight run."""
    from skfem_granular.cli import main

    straight = tmp_path / "straight"
    Simulation(_heap(300), output_dir=straight).run(progress=False)
    text = (straight / "history.csv").read_text()
    for row, column in ((10, 7), (270, 9)):
        folder = tmp_path / f"row{row}"
        folder.mkdir()
        for name in ("checkpoint.npz", "checkpoint.prev.npz"):
            (folder / name).write_bytes((straight / name).read_bytes())
        lines = text.splitlines(keepends=True)
        vals = lines[row].split(",")
        vals[column] = vals[column].replace("1", "2", 1) if "1" in vals[column] else "1"
        lines[row] = ",".join(vals)
        (folder / "history.csv").write_text("".join(lines))
        capsys.readouterr()
        if row == 10:
            before = {p.name: p.read_bytes() for p in folder.iterdir()}
            assert main(["run", "--resume", str(folder), "--no-progress"]) == 2
            err = capsys.readouterr().err.strip().splitlines()
            assert len(err) == 1, err
            assert "history.csv'" in err[0] and "rows 1-299 are not the ones" in err[0]
            assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
        else:
            assert main(["run", "--resume", str(folder), "--no-progress"]) == 0
            err = capsys.readouterr().err.strip().splitlines()
            assert len(err) == 1 and err[0].startswith("skfem-granular: warning: "), err
            assert "rows 1-299 are not the ones" in err[0]
            assert err[0].endswith("resuming from checkpoint.prev.npz (step 250)")
            assert (folder / "history.csv").read_text() == text


def test_corrupt_newest_checkpoint_falls_back_to_the_previous(tmp_path, capsys):
    """checkpoint.npz cut short (a disk error, say): the run resumes from checkpoint.prev.npz
    with one line of warning (also in the summary), byte for byte the straight run; the
    checkpoint it resumed from becomes the newest, so the ring is good again."""
    straight = tmp_path / "straight"
    Simulation(_heap(300), output_dir=straight).run(progress=False)
    part = tmp_path / "part"
    Simulation(_heap(280), output_dir=part).run(progress=False)  # checkpoints 250, 200
    blob = (part / "checkpoint.npz").read_bytes()
    (part / "checkpoint.npz").write_bytes(blob[:len(blob) // 2])
    capsys.readouterr()
    sim = Simulation.resume(part, t_end=300 * 2e-4)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "checkpoint.npz'" in err[0] and "not a readable file" in err[0]
    assert err[0].endswith("resuming from checkpoint.prev.npz (step 200)")
    assert sim.steps_done == 200
    res = sim.run(progress=False)
    assert (part / "history.csv").read_bytes() == (straight / "history.csv").read_bytes()
    assert len(res.summary["warnings"]) == 1
    assert _k_of(part / "checkpoint.npz") == 300 and _k_of(part / "checkpoint.prev.npz") == 250
    # both unusable: the newest's reason, in one line
    (part / "checkpoint.prev.npz").write_bytes(b"PK not a zip")
    (part / "checkpoint.npz").write_bytes(b"")
    with pytest.raises(ValueError, match=r"checkpoint.npz'.*not a readable file"):
        Simulation.resume(part)


def test_only_the_previous_checkpoint_left(tmp_path, capsys):
    """No checkpoint.npz (removed by hand): the previous one is used, and says so."""
    part = tmp_path / "part"
    Simulation(_heap(120), output_dir=part).run(progress=False)  # checkpoints 50, 100
    (part / "checkpoint.npz").unlink()
    capsys.readouterr()
    sim = Simulation.resume(part)
    assert sim.steps_done == 50
    assert "no checkpoint.npz" in capsys.readouterr().err


@pytest.mark.parametrize("links", [True, False])
def test_kept_file_is_complete_at_every_moment(tmp_path, monkeypatch, links):
    """atomic_write(..., keep=...): the old file becomes the kept one only once the new one
    is complete (a failed write changes neither); without hard links, a copy."""
    import errno
    import os

    from skfem_granular.io import atomic_write, partial_files

    if not links:
        def no_link(*args, **kwargs):
            raise OSError(errno.EPERM, "no links here")
        monkeypatch.setattr(os, "link", no_link)
    path, kept = tmp_path / "c.npz", tmp_path / "c.prev.npz"
    atomic_write(path, lambda tmp: Path(tmp).write_text("one"), keep=kept)
    assert path.read_text() == "one" and not kept.exists()
    atomic_write(path, lambda tmp: Path(tmp).write_text("two"), keep=kept, fsync=True)
    assert (path.read_text(), kept.read_text()) == ("two", "one")

    def fail(tmp):
        Path(tmp).write_text("thr")
        raise OSError(errno.ENOSPC, "full")

    with pytest.raises(OSError):
        atomic_write(path, fail, keep=kept)
    assert (path.read_text(), kept.read_text()) == ("two", "one")
    atomic_write(path, lambda tmp: Path(tmp).write_text("three"), keep=kept)
    assert (path.read_text(), kept.read_text()) == ("three", "two")
    assert not partial_files(tmp_path)
