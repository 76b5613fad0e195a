"""An output folder belongs to one run; signals and write errors leave it whole.

Each case checks the exit status, the one line on stderr and, by hashes, that
no file of the earlier run changed (unless ``--overwrite`` was given):

- a new run, or a failing one, into a finished run's folder is refused; with
  ``--overwrite`` the old run's files are removed first;
- ``--resume`` refuses a ``--t-end`` before the checkpoint's time;
- a live run's lock refuses a second run (one line naming the pid); a lock
  whose process is gone is taken over; two runs started into one folder at
  once: one runs, the other is refused;
- the lock file is readable or absent whatever system call of its creation a
  kill comes before (a child process exits there, for every one of them, into
  an empty folder, over a dead process's lock and over an empty lock): the next
  run takes the folder over; a process stopped there while another takes the
  folder: exactly one holds it, the other is refused naming its pid; an empty
  or garbled lock is taken over;
- two SIGTERMs (or SIGINTs) 50 ms apart: exit status 143 (130), the history,
  the summary and the checkpoint written, and the run resumes bit for bit;
  SIGTERM/SIGINT during start-up: one line, 143/130, no traceback;
- a full disk (an injected ``ENOSPC``, and a real 2 MB tmpfs when the tests run
  as root) during the run: exit status 1, one line, the files written before
  intact, and the run resumes once there is room;
- a kill during the first checkpoint write: ``--resume`` says so.
"""

from __future__ import annotations

import errno
import hashlib
import json
import os
import signal
import socket
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import pytest

from skfem_granular.cli import main
from skfem_granular.io import read_csv
from skfem_granular.scene import Scene, TimeSpec
from skfem_granular.simulation import Simulation
from skfem_granular.simulation.folder import LOCK_NAME, FolderInUseError

SHORT = ["single-particle", "--t-end", "1e-4", "--vtu-every", "2", "--checkpoint-every", "5",
         "--no-progress"]


def _hashes(d: Path) -> dict:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(d.iterdir())
            if p.is_file()}


def _one_line(capsys, *parts):
    cap = capsys.readouterr()
    lines = cap.err.strip().splitlines()
    assert len(lines) == 1, cap.err
    assert "Traceback" not in cap.err
    for part in parts:
        assert part in lines[0], lines[0]
    return lines[0]


@pytest.fixture
def finished(tmp_path, capsys):
    """A finished run (20 steps, checkpoints every 5) and its files' hashes."""
    out = tmp_path / "run"
    assert main(["run", *SHORT, "--t-end", "2e-4", "--out", str(out)]) == 0
    capsys.readouterr()
    return out, _hashes(out)


def test_new_run_into_a_finished_runs_folder_is_refused(finished, capsys):
    out, before = finished
    assert main(["run", *SHORT, "--out", str(out)]) == 2
    _one_line(capsys, f"output folder {str(out)!r}: holds another run's output",
              "--overwrite", "--resume")
    assert _hashes(out) == before


def test_failing_run_into_a_finished_runs_folder_changes_nothing(finished, capsys,
                                                                  monkeypatch):
    """A run whose first step fails is refused before it starts: the old files stay."""
    from skfem_granular.coupled import stepper

    def fail(self, *a, **k):
        raise stepper.SimulationError("no convergence (made up)")
        yield  # a generator, as the stepper's evolve

    monkeypatch.setattr(stepper.CoupledStepper, "evolve", fail)
    out, before = finished
    assert main(["run", *SHORT, "--out", str(out)]) == 2
    _one_line(capsys, "holds another run's output")
    assert _hashes(out) == before
    fresh = out.parent / "fresh"  # the same run into an empty folder fails with exit status 1
    assert main(["run", *SHORT, "--out", str(fresh)]) == 1
    _one_line(capsys, "no convergence (made up)", "history and last good state written")
    assert json.loads((fresh / "summary.json").read_text())["status"] == "failed"


def test_overwrite_removes_the_old_runs_files_first(finished, tmp_path, capsys):
    out, before = finished
    (out / "notes.txt").write_text("mine")  # not a run's file: left alone
    assert main(["run", *SHORT, "--checkpoint-every", "0", "--out", str(out),
                 "--overwrite"]) == 0
    capsys.readouterr()
    after = _hashes(out)
    assert "checkpoint.npz" not in after  # the old run's; this one writes none
    assert "flow_00010.vtu" in before and "flow_00010.vtu" not in after  # old frames gone
    assert after["notes.txt"] == hashlib.sha256(b"mine").hexdigest()
    ref = tmp_path / "ref"
    assert main(["run", *SHORT, "--checkpoint-every", "0", "--out", str(ref)]) == 0
    capsys.readouterr()
    assert (out / "history.csv").read_bytes() == (ref / "history.csv").read_bytes()
    assert LOCK_NAME not in after


def test_library_folder_belongs_to_one_run(tmp_path):
    sc = Scene.bundled("single_particle")
    short = replace(sc, time=TimeSpec(2e-5, 1e-5), output_dir=None)
    Simulation(short, output_dir=tmp_path).run(progress=False)
    before = _hashes(tmp_path)
    with pytest.raises(FolderInUseError, match="holds another run's output"):
        Simulation(short, output_dir=tmp_path)
    assert isinstance(FolderInUseError("x"), ValueError)
    res = Simulation(short, output_dir=tmp_path, overwrite=True).run(progress=False)
    assert res.summary["status"] == "completed"
    assert _hashes(tmp_path)["history.csv"] == before["history.csv"]  # same run again


def test_resume_refuses_a_t_end_before_the_checkpoint(finished, capsys):
    out, before = finished
    assert main(["run", "--resume", str(out), "--t-end", "1e-4", "--no-progress"]) == 2
    _one_line(capsys, "t_end (--t-end) = 0.0001", "must be >= 0.0002")
    assert _hashes(out) == before


def test_resume_to_an_absurd_t_end_is_one_line(finished, capsys):
    out, before = finished
    assert main(["run", "--resume", str(out), "--t-end", "1e300", "--no-progress"]) == 2
    _one_line(capsys, "time.t_end / time.dt = 1e+300 / 1e-05", "more than max_steps")
    assert _hashes(out) == before


def test_resume_of_a_finished_run_to_its_end_changes_no_row(finished, capsys):
    out, before = finished
    assert main(["run", "--resume", str(out), "--no-progress"]) == 0
    capsys.readouterr()
    assert (out / "history.csv").read_bytes() == (out.parent / "run" / "history.csv").read_bytes()
    assert _hashes(out)["history.csv"] == before["history.csv"]


def _write_lock(out: Path, pid: int, host: str | None = None):
    out.mkdir(parents=True, exist_ok=True)
    (out / LOCK_NAME).write_text(json.dumps({"pid": pid, "host": host or socket.gethostname()}))


def test_live_lock_refuses_a_second_run(tmp_path, capsys):
    out = tmp_path / "locked"
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        _write_lock(out, holder.pid)
        assert main(["run", *SHORT, "--out", str(out)]) == 2
        _one_line(capsys, "in use by a running simulation", f"pid {holder.pid}", LOCK_NAME)
        assert main(["run", "--resume", str(out), "--no-progress"]) == 2
        _one_line(capsys, "in use by a running simulation")
        assert sorted(p.name for p in out.iterdir()) == [LOCK_NAME]
    finally:
        holder.kill()
        holder.wait()
    # its process gone: the lock is taken over, and released at the end
    assert main(["run", *SHORT, "--out", str(out)]) == 0
    capsys.readouterr()
    assert not (out / LOCK_NAME).exists()


def test_lock_of_another_host_is_never_taken_over(tmp_path, capsys):
    out = tmp_path / "elsewhere"
    _write_lock(out, 1, host="another-host.invalid")
    assert main(["run", *SHORT, "--out", str(out)]) == 2
    _one_line(capsys, "pid 1 on another-host.invalid")


def _sigint_default():
    """In the child: SIGINT as a shell's foreground command gets it (a background job of a
    shell without job control would inherit it ignored, and Python leaves it so)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _launch(argv, cwd):
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen([sys.executable, "-m", "skfem_granular.cli", "run", *argv],
                            cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, preexec_fn=_sigint_default)


def test_two_runs_started_into_one_folder_at_once(tmp_path, capsys):
    out = tmp_path / "both"
    argv = [*SHORT, "--t-end", "3e-4", "--out", str(out)]
    procs = [_launch(argv, tmp_path) for _ in range(2)]
    results = [(p.wait(timeout=300), p.communicate()[1]) for p in procs]
    codes = sorted(c for c, _ in results)
    assert codes == [0, 2], results
    err = next(e for c, e in results if c == 2).strip().splitlines()
    assert len(err) == 1 and ("in use by a running simulation" in err[0]
                              or "holds another run's output" in err[0]), err
    ref = tmp_path / "ref"
    assert main(["run", *argv[:-2], "--out", str(ref)]) == 0
    capsys.readouterr()
    assert _hashes(out) == {k: v for k, v in _hashes(ref).items() if k != "summary.json"} | {
        "summary.json": _hashes(out)["summary.json"]}


def _wait_rows(proc, history: Path, rows: int, timeout=120.0):
    t0 = time.monotonic()
    while True:
        assert proc.poll() is None, proc.communicate()
        try:
            if history.read_text().count("\n") - 1 >= rows:
                return
        except FileNotFoundError:
            pass
        assert time.monotonic() - t0 < timeout
        time.sleep(0.002)


@pytest.mark.parametrize("name", ["SIGTERM", "SIGINT"])
def test_two_signals_50_ms_apart_leave_a_resumable_run(tmp_path, capsys, name):
    sig = getattr(signal, name)
    out = tmp_path / "twice"
    argv = [*SHORT, "--t-end", "4e-4", "--checkpoint-every", "3"]
    proc = _launch([*argv, "--out", str(out)], tmp_path)
    _wait_rows(proc, out / "history.csv", 12)
    proc.send_signal(sig)
    time.sleep(0.05)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + sig, err
    assert "Traceback" not in err and f"stopped by {name}" in err
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "stopped" and s["stopped_by"] == name
    h = read_csv(out / "history.csv")
    assert h["t"].shape[0] == s["steps"] >= 12
    assert (out / "checkpoint.npz").exists() and not (out / LOCK_NAME).exists()
    ref = tmp_path / "ref"
    assert main(["run", *argv, "--out", str(ref)]) == 0
    assert main(["run", "--resume", str(out), "--no-progress"]) == 0
    capsys.readouterr()
    assert (out / "history.csv").read_bytes() == (ref / "history.csv").read_bytes()


@pytest.mark.parametrize("name", ["SIGTERM", "SIGINT"])
def test_signal_during_start_up_is_one_line(tmp_path, name):
    """The signal comes while the mesh is built (the folder exists, no history yet)."""
    sig = getattr(signal, name)
    out = tmp_path / "early"
    proc = _launch([*SHORT, "--mesh", "uniform", "--out", str(out)], tmp_path)
    t0 = time.monotonic()
    while not out.exists():
        assert proc.poll() is None and time.monotonic() - t0 < 60
        time.sleep(0.001)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    lines = err.strip().splitlines()
    assert proc.returncode == 128 + sig, err
    assert "Traceback" not in err and len(lines) <= 2, err
    assert f"stopped by {name}" in lines[-1]


def test_full_disk_during_the_run_is_one_line_and_keeps_what_was_written(tmp_path, capsys,
                                                                          monkeypatch):
    from skfem_granular.io import pvd

    out = tmp_path / "full"
    real = pvd.PVDSeries.write
    calls = []

    def write(self, t, save):
        calls.append(t)
        if len(calls) > 8:  # the disk fills up after four frames of each series
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(out / "flow_00004.vtu"))
        return real(self, t, save)

    monkeypatch.setattr(pvd.PVDSeries, "write", write)
    assert main(["run", *SHORT, "--out", str(out)]) == 1
    _one_line(capsys, "writing the output failed: No space left on device",
              "flow_00004.vtu", "the files written before are intact")
    h = read_csv(out / "history.csv")
    assert h["t"].shape[0] >= 6
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "failed" and "No space left on device" in s["failed"]
    monkeypatch.setattr(pvd.PVDSeries, "write", real)
    assert main(["run", "--resume", str(out), "--no-progress"]) == 0  # from step 5
    capsys.readouterr()
    ref = tmp_path / "ref"
    assert main(["run", *SHORT, "--out", str(ref)]) == 0
    capsys.readouterr()
    assert (out / "history.csv").read_bytes() == (ref / "history.csv").read_bytes()


def test_full_disk_at_the_summary_is_one_line(tmp_path, capsys, monkeypatch):
    from skfem_granular.simulation import recorder

    def full(path, write, **kw):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))

    monkeypatch.setattr(recorder, "atomic_write", full)
    out = tmp_path / "full"
    assert main(["run", *SHORT, "--checkpoint-every", "0", "--out", str(out)]) == 1
    _one_line(capsys, "writing the output failed: No space left on device", "summary.json")
    assert read_csv(out / "history.csv")["t"].shape == (10,)


def test_resume_after_a_kill_in_the_first_checkpoint_says_so(tmp_path, capsys):
    out = tmp_path / "killed"
    assert main(["run", *SHORT, "--checkpoint-every", "0", "--out", str(out)]) == 0
    (out / "summary.json").unlink()
    (out / ".partial-checkpoint-x1y2.npz").write_bytes(b"PK half a file")
    assert main(["run", "--resume", str(out), "--no-progress"]) == 2
    _one_line(capsys, "no checkpoint.npz", "killed while writing its first checkpoint",
              "--overwrite")
    (out / ".partial-checkpoint-x1y2.npz").unlink()
    assert main(["run", "--resume", str(out), "--no-progress"]) == 2
    _one_line(capsys, "no checkpoint.npz", "the run there wrote none")
    assert main(["run", "--resume", str(tmp_path / "empty"), "--no-progress"]) == 2
    _one_line(capsys, "no checkpoint.npz", "no run's output there")


def test_partial_files_are_removed_on_any_start(tmp_path, capsys):
    out = tmp_path / "fresh"
    out.mkdir()
    (out / ".partial-history-abc.csv").write_text("torn")
    assert main(["run", *SHORT, "--out", str(out)]) == 0
    capsys.readouterr()
    assert not list(out.glob(".partial-*"))


def test_full_disk_at_the_lock_file_is_one_line(tmp_path, capsys, monkeypatch):
    from skfem_granular.simulation import folder

    def full(*a, **k):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(tmp_path / "x" / LOCK_NAME))

    monkeypatch.setattr(folder.os, "open", full)
    assert main(["run", *SHORT, "--out", str(tmp_path / "x")]) == 1
    _one_line(capsys, "output: No space left on device", LOCK_NAME)


def test_second_signal_in_the_callers_loop_still_writes_everything(tmp_path):
    """Library use: the second SIGTERM lands in the caller's loop body (StopNow, a
    BaseException, reaches the caller); the generator, closed, writes the history of the
    accepted steps and the summary, and restores the handlers."""
    from skfem_granular.signals import StopNow

    before = signal.getsignal(signal.SIGTERM)
    sc = replace(Scene.bundled("single_particle"), time=TimeSpec(1e-4, 1e-5), output_dir=None)
    sim = Simulation(sc, output_dir=tmp_path)
    steps = 0
    with pytest.raises(StopNow):
        for _ in sim.evolve():
            steps += 1
            if steps == 3:
                signal.raise_signal(signal.SIGTERM)
                signal.raise_signal(signal.SIGTERM)
    s = sim.result.summary
    assert (s["status"], s["stopped_by"], s["stopped_at_once"], s["steps"]) == (
        "stopped", "SIGTERM", True, 3)
    assert json.loads((tmp_path / "summary.json").read_text())["stopped_at_once"] is True
    assert read_csv(tmp_path / "history.csv")["t"].shape == (3,)
    assert signal.getsignal(signal.SIGTERM) is before and not (tmp_path / LOCK_NAME).exists()


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() != 0,
                    reason="mounting a small file system needs root")
def test_a_small_file_system_fills_up(tmp_path, capsys):
    """A real full disk: a 2 MB tmpfs fills up after 8 steps of a frame each. Exit status
    1 and one line; the history (8 rows), the PVD indices, their frames and the checkpoint
    (step 5) stay readable; once there is room, the run resumes to the uninterrupted
    run's history, byte for byte."""
    import meshio

    from skfem_granular.io import read_pvd
    from skfem_granular.simulation import checkpoint

    mnt = tmp_path / "small"
    mnt.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(mnt)],
                      capture_output=True).returncode:
        pytest.skip("cannot mount a tmpfs here")
    try:
        out = mnt / "run"
        argv = [*SHORT, "--t-end", "6e-4", "--vtu-every", "1"]
        assert main(["run", *argv, "--out", str(out)]) == 1
        _one_line(capsys, "writing the output failed: No space left on device",
                  "the files written before are intact")
        rows = read_csv(out / "history.csv")["t"].shape[0]
        assert (out / "history.csv").read_text().endswith("\n")
        k = checkpoint.load(out)["k"]
        assert 5 <= k <= rows < 60
        for series in ("flow", "particles"):
            for _, f in read_pvd(out / f"{series}.pvd"):
                assert meshio.read(f).points.shape[0] > 0
        assert json.loads((out / "summary.json").read_text())["status"] == "failed"
        subprocess.run(["mount", "-o", "remount,size=64m", str(mnt)], check=True)
        assert main(["run", "--resume", str(out), "--no-progress"]) == 0
        capsys.readouterr()
        ref = tmp_path / "ref"
        assert main(["run", *argv, "--out", str(ref)]) == 0
        capsys.readouterr()
        assert (out / "history.csv").read_bytes() == (ref / "history.csv").read_bytes()
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True)


# ---------------------------------------------------------------- the lock file itself
_KILL_DRIVER = r'''
import json, os, select, socket, sys
from pathlib import Path

from skfem_granular.simulation import folder
from skfem_granular.simulation.folder import LOCK_NAME, FolderInUseError, FolderLock

base, scenario, variant = Path(sys.argv[1]), sys.argv[2], sys.argv[3]
CALLS = {"open", "write", "close", "fstat", "link", "unlink", "rename", "listdir", "kill"}
real_os = os


class Proxy:
    """``os`` for the lock's code: ``action`` runs before its ``at``-th system call."""

    def __init__(self, at, action):
        self.at, self.action, self.n = at, action, 0

    def __getattr__(self, name):
        value = getattr(real_os, name)
        if name not in CALLS:
            return value

        def call(*a, **k):
            self.n += 1
            if self.n == self.at:
                self.action()
            return value(*a, **k)
        return call


def dead_pid():
    pid = os.fork()
    if pid == 0:
        os._exit(0)
    os.waitpid(pid, 0)
    return pid


def lock_bytes(d):
    try:
        return (d / LOCK_NAME).read_bytes().decode("latin-1")
    except FileNotFoundError:
        return None


for k in range(1, 200):
    d = base / f"{scenario}-{variant}-{k}"
    d.mkdir()
    if scenario == "stale":
        (d / LOCK_NAME).write_text(json.dumps({"pid": dead_pid(), "host": socket.gethostname()}))
    elif scenario == "garbled":
        (d / LOCK_NAME).write_bytes(b"")  # an earlier version, killed before writing it
    rec = {"k": k, "before": lock_bytes(d), "driver": os.getpid()}
    r1, w1 = os.pipe()
    r2, w2 = os.pipe()
    pid = os.fork()
    if pid == 0:
        code = 1
        try:
            os.close(r1)
            os.close(w2)
            if variant == "kill":
                def action():
                    os._exit(137)
            else:
                def action():  # stopped here until the driver has tried the folder
                    os.write(w1, b"p")
                    os.read(r2, 1)
            folder.os = Proxy(k, action)
            try:
                FolderLock(d).acquire()
                code = 0
            except FolderInUseError:
                code = 3
        finally:
            os._exit(code)
    os.close(w1)
    os.close(r2)
    rec["child_pid"] = pid
    if variant == "freeze":
        select.select([r1], [], [], 60)
        rec["paused"] = os.read(r1, 1) == b"p"
        mine = FolderLock(d, "driver")
        try:
            mine.acquire()
            rec["driver_lock"] = "held"
        except FolderInUseError as exc:
            rec["driver_lock"] = str(exc)
        if rec["paused"]:
            os.write(w2, b"g")
    rec["child"] = os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])
    os.close(r1)
    os.close(w2)
    if rec.get("driver_lock") == "held":
        rec["lock_while_driver_holds"] = lock_bytes(d)
        mine.release()
    rec["lock"] = lock_bytes(d)
    nxt = FolderLock(d, "next")
    try:
        nxt.acquire()
        rec["next"] = "held"
        nxt.release()
    except FolderInUseError as exc:
        rec["next"] = str(exc)
    rec["left"] = sorted(os.listdir(d))
    print(json.dumps(rec), flush=True)
    if (variant == "kill" and rec["child"] == 0) or (variant == "freeze" and not rec["paused"]):
        break  # the acquisition ended before its k-th system call: every point was tried
'''


def _pid_in(text):
    return None if text is None else json.loads(text)["pid"]


@pytest.mark.parametrize("scenario", ["fresh", "stale", "garbled"])
def test_a_kill_between_any_two_system_calls_of_the_lock_leaves_it_readable_or_absent(
        tmp_path, scenario):
    """A child process taking the lock (into an empty folder, over a dead process's lock,
    over an empty lock) is killed (os._exit) before its k-th system call, for every k: the
    lock is then absent, the child's (readable JSON) or the one that was there before, and
    the next run takes the folder and leaves nothing behind (no lock, no temporary)."""
    out = subprocess.run([sys.executable, "-c", _KILL_DRIVER, str(tmp_path), scenario, "kill"],
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    recs = [json.loads(line) for line in out.stdout.splitlines()]
    assert recs[-1]["child"] == 0 and len(recs) >= {"fresh": 7, "stale": 12, "garbled": 10}[
        scenario], recs  # every point up to a completed acquisition
    for r in recs:
        assert r["child"] in (137, 0), r
        assert r["lock"] in (None, r["before"]) or _pid_in(r["lock"]) == r["child_pid"], r
        assert r["next"] == "held" and r["left"] == [], r


@pytest.mark.parametrize("scenario", ["fresh", "stale", "garbled"])
def test_a_second_run_while_the_first_is_stopped_at_any_system_call(tmp_path, scenario):
    """The child is stopped (alive) before its k-th system call while another process takes
    the folder, then continues: exactly one of them holds the lock; the other is refused
    with one line naming the holder's pid."""
    out = subprocess.run([sys.executable, "-c", _KILL_DRIVER, str(tmp_path), scenario,
                          "freeze"], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    recs = [json.loads(line) for line in out.stdout.splitlines()]
    assert len(recs) >= 7 and not recs[-1]["paused"], recs
    outcomes = set()
    for r in recs[:-1]:
        if r["driver_lock"] == "held":  # the child's lock was not in place yet
            assert r["child"] == 3, r  # refused when it went on
            assert _pid_in(r["lock_while_driver_holds"]) == r["driver"], r
            assert r["lock"] is None, r
        else:
            assert f"in use by a running simulation (pid {r['child_pid']} on " in \
                r["driver_lock"], r
            assert "\n" not in r["driver_lock"]
            assert r["child"] == 0 and _pid_in(r["lock"]) == r["child_pid"], r
        outcomes.add(r["driver_lock"] == "held")
        assert r["next"] == "held" and r["left"] == [], r
    assert outcomes == {True, False}  # both orders were met


@pytest.mark.parametrize("content", [b"", b"{", b"null", b"[1, 2]", b'{"pid": "7"}',
                                     b'{"pid": 7}', b"\x00\xff\xfe garbage\n"])
def test_an_unreadable_lock_is_taken_over(tmp_path, content):
    from skfem_granular.simulation.folder import OutputFolder

    (tmp_path / LOCK_NAME).write_bytes(content)
    with OutputFolder(tmp_path) as f:
        held = json.loads((tmp_path / LOCK_NAME).read_text())
        assert f.held and held["pid"] == os.getpid() and held["host"] == socket.gethostname()
    assert list(tmp_path.iterdir()) == []


def test_an_empty_lock_left_by_a_kill_is_taken_over_by_the_next_run(tmp_path, capsys):
    out = tmp_path / "run"
    out.mkdir()
    (out / LOCK_NAME).write_bytes(b"")
    assert main(["run", *SHORT, "--out", str(out)]) == 0
    capsys.readouterr()
    assert not (out / LOCK_NAME).exists() and (out / "summary.json").exists()


def test_a_lock_with_this_process_id_from_an_earlier_process_is_taken_over(tmp_path):
    """A restarted container can give a run the process id of the killed one: a lock with
    this process's id but not one of its locks is stale; one of its own is not."""
    from skfem_granular.simulation.folder import FolderLock

    _write_lock(tmp_path, os.getpid())
    first = FolderLock(tmp_path)
    first.acquire()
    with pytest.raises(FolderInUseError, match=f"pid {os.getpid()} on "):
        FolderLock(tmp_path).acquire()  # this process's own live lock
    first.release()
    assert list(tmp_path.iterdir()) == []


def test_lock_without_hard_links(tmp_path, monkeypatch):
    """A file system that cannot make hard links: the lock is created and written in one
    call instead, and is readable and released as usual."""
    from skfem_granular.simulation import folder

    def no_links(*a, **k):
        raise OSError(errno.EPERM, os.strerror(errno.EPERM))

    monkeypatch.setattr(folder.os, "link", no_links)
    lock = folder.FolderLock(tmp_path)
    lock.acquire()
    assert json.loads((tmp_path / LOCK_NAME).read_text())["pid"] == os.getpid()
    assert sorted(p.name for p in tmp_path.iterdir()) == [LOCK_NAME]
    with pytest.raises(FolderInUseError):
        folder.FolderLock(tmp_path).acquire()
    lock.release()
    assert list(tmp_path.iterdir()) == []
