"""Checkpoints: the whole state of a run in one plain-data file, and resuming from it.

A checkpoint holds everything the next step depends on: the scene, the step
count, the fluid state with *both* BDF2 histories (``u_n``, ``u_{n-1}``) and
the particle histories, the DEM state (positions, velocities, BDF2 history,
contact springs), the mesh with its meshing recipe and the reference
positions of the particles on it, the step controller's state, the counters
and the frames written so far. The stepper hands over its state
(``checkpoint_state``) and is rebuilt from it on resume; it refactorises at
each checkpoint too, so a run resumed from a checkpoint reproduces the run
that wrote it bit for bit (tested, also after a SIGKILL at a random moment).

The history rows stay in ``history.csv``, which holds them anyway (appended
and synced before every checkpoint): a checkpoint records how many rows it
follows, the SHA-256 of the file's bytes up to the row before its last
(header line included) and that last row itself, so its size and the time to
write it do not grow with the run. Resuming reads the rows back from
``history.csv`` (``%.17g`` text: the same doubles), refuses a file that is
shorter or whose bytes differ (one line naming the file), and the resumed
run rewrites the file to the checkpoint's rows. The last row is kept in the
checkpoint because a run resumed past the end of the run it continues gives
that row the time of its clock (``Simulation._continue_clock``), so the
file's copy of it may differ in ``t``.

Checkpoints form a ring of two: ``checkpoint.npz`` (the newest) and
``checkpoint.prev.npz`` (the one before it). A new checkpoint is written to a
temporary file and synced; only then is the newest kept as the previous one
(a hard link, renamed; a copy where links cannot be made) and the new file
renamed onto ``checkpoint.npz``, so ``checkpoint.npz`` always names a
complete checkpoint and the last good one is never removed before the new
one is whole. :func:`load` reads the newest and, when it cannot be read or
does not fit ``history.csv``, the previous one, with a one-line warning
naming the reason; a run resumed from the previous one makes it the newest
again (:func:`promote`) when it starts writing.

The file is plain data (:mod:`skfem_granular.io.plain`): a zip of ``.npy``
arrays (float64, int64 or bool) and ``header.json`` (format name and
version, every other value, the type of every object), written atomically
and synced to the disk. Open it with ``numpy.load(path,
allow_pickle=False)`` (arrays by field path, e.g. ``"stepper.state.u_n"``)
or ``unzip -p checkpoint.npz header.json``. Reading it runs no code from the
file: objects are rebuilt only for an allowlisted set of types
(:data:`REGISTRY`), through their constructors, so the scene is validated as
a scene read from TOML is; every array's dtype and shape is checked against
the header and the field's meaning (the fluid vectors against the mesh, the
particle arrays against the number of particles), every float must be finite
except the history's and the error estimate's, and unknown versions, keys,
fields or arrays are refused, each with one line naming the field.

Version 4 keeps the history in ``history.csv``; version 3 (the whole history
in the checkpoint) is still read. Versions 1 and 2 were ``checkpoint.pkl``
files; they are refused, never read (loading such a file can run arbitrary
code): no pickle is used anywhere.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import re
from pathlib import Path

import numpy as np
import skfem

import meshing

from ..coupled.flow_size import FlowSizing
from ..coupled.state import CoupledState
from ..coupled.wake import WakeGrading
from ..dem import ContactLaw, Polygon, PrescribedMotion
from ..fluid.properties import Fluid
from ..io import History, keep_previous, plain
from ..scene import Effects, MeshSpec, ParticleSpec, Scene, TimeSpec

FORMAT = "skfem-granular checkpoint"
#: The format version written: the history stays in ``history.csv``.
VERSION = 4
#: The versions read: 3 held the whole history (1 and 2, pickle files, are not read).
READ_VERSIONS = (3, 4)
#: The newest checkpoint.
FILENAME = "checkpoint.npz"
#: The checkpoint before the newest (the ring's other file).
PREVIOUS_FILENAME = "checkpoint.prev.npz"
#: The history file whose rows a checkpoint follows.
HISTORY_FILENAME = "history.csv"
#: The pickle checkpoints of earlier versions: refused, never unpickled.
LEGACY_FILENAME = "checkpoint.pkl"

HEADER_KEYS = {"format", "version", "written_by", "content"}
#: A checkpoint's content (``history``: version 3 the rows, version 4 how many, their
#: digest and the last).
CONTENT_KEYS = {"scene", "k", "dem", "stepper", "history", "frames"}


def _polygon(d):
    return Polygon(d["vertices"], name="polygon")


def _mesh_fields(m):
    return {"doflocs": m.doflocs, "t": m.t,
            "boundaries": None if m.boundaries is None else dict(m.boundaries),
            "subdomains": None if m.subdomains is None else dict(m.subdomains)}


def _index_dict(name, d, n):
    if d is None:
        return None
    if not isinstance(d, dict):
        raise ValueError(f"{name}: must be a dict of index arrays or None")
    for k, v in d.items():
        if not (isinstance(v, np.ndarray) and v.ndim == 1 and v.dtype.kind == "i"):
            raise ValueError(f"{name}.{k}: must be a 1-D integer array")
        if v.size and (v.min() < 0 or v.max() >= n):
            raise ValueError(f"{name}.{k}: indices must be in [0, {n})")
    return d


def _mesh(d):
    p, t = d["doflocs"], d["t"]
    if not (isinstance(p, np.ndarray) and p.dtype == np.float64 and p.ndim == 2
            and p.shape[0] == 2 and p.shape[1] >= 3):
        raise ValueError("doflocs: must be a (2, N) float64 array, N >= 3")
    if not (isinstance(t, np.ndarray) and t.dtype.kind == "i" and t.ndim == 2
            and t.shape[0] == 3 and t.shape[1] >= 1):
        raise ValueError("t: must be a (3, T) integer array, T >= 1")
    if t.min() < 0 or t.max() >= p.shape[1]:
        raise ValueError(f"t: vertex indices must be in [0, {p.shape[1]})")
    a, b, c = p[:, t[0]], p[:, t[1]], p[:, t[2]]
    area = 0.5 * np.abs((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
    scale = float(np.ptp(p, axis=1).max()) ** 2
    bad = np.flatnonzero(~(area > 1e-14 * scale))
    if bad.size:
        raise ValueError(f"t: triangle {bad[0]} has no area (its vertices coincide or lie on "
                         f"a line; {bad.size} such triangles): not a mesh")
    mesh = skfem.MeshTri(p, t.astype(np.int32), sort_t=False)
    b = _index_dict("boundaries", d["boundaries"], mesh.facets.shape[1])
    s = _index_dict("subdomains", d["subdomains"], t.shape[1])
    return skfem.MeshTri(p, t.astype(np.int32), _boundaries=b, _subdomains=s, sort_t=False)


#: The types a checkpoint may hold besides plain values and arrays. Dataclasses are stored
#: as their fields, so a field added to one of them (CoupledState, say) is stored and read
#: back with no change here.
REGISTRY_DATACLASSES = (CoupledState, meshing.BodyFittedMesh, meshing.Recipe, Scene,
                        ParticleSpec, PrescribedMotion, MeshSpec, TimeSpec, Effects, Fluid,
                        ContactLaw, FlowSizing, WakeGrading)
REGISTRY_CUSTOM = (
    plain.Custom(Polygon, ("vertices",), lambda p: {"vertices": p.vertices}, _polygon,
                 name="skfem_granular.dem.Polygon"),
    plain.Custom(skfem.MeshTri, ("doflocs", "t", "boundaries", "subdomains"), _mesh_fields,
                 _mesh, name="skfem.MeshTri"),
)
REGISTRY = plain.Registry(dataclasses=REGISTRY_DATACLASSES, custom=REGISTRY_CUSTOM)

#: Fields that may hold NaN or inf (besides dataclass fields whose default is NaN):
#: the history (error estimates of fixed-step runs, fluid energy of dry runs).
_NONFINITE_FIELDS = re.compile(r"^history\.")


def _nonfinite_ok(path: str) -> bool:
    return bool(_NONFINITE_FIELDS.match(path))


# ---------------------------------------------------------------------- history
def _step_value(v):
    """A step column's value as the row held it: an int stays an int, the rest floats."""
    if isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_)):
        return int(v)
    return float(v)


def _last_row(hist: History, k: int) -> dict | None:
    """Row ``k`` (the last a checkpoint after step ``k`` follows), or None for ``k = 0``."""
    if k == 0:
        return None
    r = hist.rows[k - 1]
    return {"step": {c: _step_value(r.get(c, np.nan)) for c in hist.STEP_COLUMNS},
            "particle": {c: np.array(r[c], dtype=float).reshape(hist.K)
                         for c in hist.PARTICLE_COLUMNS}}


def _history_digest(sim, k: int) -> str:
    """SHA-256 of ``history.csv`` from its start to the end of row ``k - 1``.

    Taken from the run's live history file (:class:`~skfem_granular.io.CSVLog`,
    flushed first if it lags), which keeps the digest as it writes; with no live
    file (a checkpoint written after the run), from the rows as that file holds them.
    """
    rows = max(k - 1, 0)
    log = getattr(getattr(sim, "_output", None), "log", None)
    if log is not None and not log.closed:
        if log.written < k:
            log.flush()
        if log.written == k:
            return log.digest(rows)
    hist = sim.history
    text = ",".join(hist.wide_header()) + "\n" + hist.wide_lines(0, rows)
    return hashlib.sha256(text.encode()).hexdigest()


def _history_rows(d, where: str, n_particles: int) -> list:
    """The rows of a version 3 checkpoint, which held them all."""
    def fail(path, problem):
        raise ValueError(f"{where}: {path}: {problem}")

    if not isinstance(d, dict) or set(d) != {"particles", "step", "particle"}:
        fail("history", "must hold 'particles', 'step' and 'particle' (and nothing else)")
    if d["particles"] != n_particles:
        fail("history.particles", f"= {d['particles']!r}: must be {n_particles} (the scene's "
                                  "particles)")
    for name, cols in (("step", History.STEP_COLUMNS), ("particle", History.PARTICLE_COLUMNS)):
        got = d[name]
        if not isinstance(got, dict) or set(got) != set(cols):
            extra = sorted(set(got) - set(cols)) if isinstance(got, dict) else []
            what = f"unknown column {extra[0]!r}" if extra else "columns missing"
            fail(f"history.{name}", f"{what} (columns: {', '.join(cols)})")
    T: int | None = None
    for c in History.STEP_COLUMNS:
        a = d["step"][c]
        if not (isinstance(a, np.ndarray) and a.ndim == 1):
            fail(f"history.step.{c}", "must be a 1-D array")
        T = a.shape[0] if T is None else T
        if a.shape != (T,):
            fail(f"history.step.{c}", f"shape {a.shape}: must be ({T},) like history.step.t")
    assert T is not None  # History has step columns
    for c in History.PARTICLE_COLUMNS:
        a = d["particle"][c]
        if not (isinstance(a, np.ndarray) and a.shape == (T, n_particles)
                and a.dtype == np.float64):
            shape = getattr(a, "shape", None)
            fail(f"history.particle.{c}", f"shape {shape}: must be a ({T}, {n_particles}) "
                                          "float array")
    t = d["step"]["t"]
    if T and not np.all(np.isfinite(t)):
        fail("history.step.t", "contains NaN or inf (must be finite)")
    rows = []
    for i in range(T):
        row = {}
        for c in History.STEP_COLUMNS:
            v = d["step"][c][i]
            row[c] = int(v) if d["step"][c].dtype == np.int64 else float(v)
        for c in History.PARTICLE_COLUMNS:
            row[c] = d["particle"][c][i].copy()
        rows.append(row)
    return rows


_SHA256 = re.compile(r"^[0-9a-f]{64}$")


def _check_history(d, where: str, K: int) -> None:
    """A version 4 checkpoint's history entry: the rows it follows, their digest, the last."""
    if not isinstance(d, dict) or set(d) != {"rows", "sha256", "last"}:
        _fail(where, "history", "must hold 'rows', 'sha256' and 'last' (and nothing else)")
    _check_count(where, "history.rows", d["rows"])
    if not (isinstance(d["sha256"], str) and _SHA256.match(d["sha256"])):
        _fail(where, "history.sha256", "must be 64 hexadecimal digits (lower case)")
    last = d["last"]
    if d["rows"] == 0 or last is None:
        if not (d["rows"] == 0 and last is None):
            _fail(where, "history.last", "must be None exactly when history.rows is 0")
        return
    if not isinstance(last, dict) or set(last) != {"step", "particle"}:
        _fail(where, "history.last", "must hold 'step' and 'particle' (and nothing else)")
    for name, cols in (("step", History.STEP_COLUMNS), ("particle", History.PARTICLE_COLUMNS)):
        got = last[name]
        if not isinstance(got, dict) or set(got) != set(cols):
            _fail(where, f"history.last.{name}", f"must hold the columns {', '.join(cols)}")
    for c, v in last["step"].items():
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            _fail(where, f"history.last.step.{c}", f"= {v!r}: must be a number")
    if not np.isfinite(last["step"]["t"]):
        _fail(where, "history.last.step.t", "must be a finite number")
    for c, a in last["particle"].items():
        _check_array(where, f"history.last.particle.{c}", a, (K,))


def _history_from_file(directory: Path, d: dict, K: int, where: str) -> list:
    """The rows a version 4 checkpoint follows, read back from ``history.csv`` and checked.

    The file must hold at least ``d["rows"]`` complete rows, its bytes up to the row
    before the last must have the checkpoint's SHA-256, and that last row must be the
    checkpoint's copy but for its time (see the module notes); the checkpoint's copy
    is the one used.
    """
    path = directory / HISTORY_FILENAME
    name = f"history {str(path)!r}"
    k = d["rows"]
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise ValueError(f"{name}: not found ({where} keeps its {k} rows there)") from None
    except OSError as exc:
        raise ValueError(f"{name}: cannot be read ({exc.strerror})") from None
    hist = History(K)
    head = (",".join(hist.wide_header()) + "\n").encode()
    if not raw.startswith(head):
        raise ValueError(f"{name}: its header line is not the one of {where} (the columns "
                         f"of a run of K = {K} particles)")
    if k == 0:
        return []
    ends = [len(head) - 1]  # where the header line and each row end
    while len(ends) <= k:
        pos = raw.find(b"\n", ends[-1] + 1)
        if pos < 0:
            raise ValueError(f"{name}: {len(ends) - 1} complete rows, fewer than the {k} "
                             f"{where} follows (the file was cut short)")
        ends.append(pos)
    cut = ends[k - 1] + 1
    sha = hashlib.sha256(memoryview(raw)[:cut]).hexdigest()
    if sha != d["sha256"]:
        what = ("header line" if k == 1 else "header and row 1" if k == 2
                else f"header and rows 1-{k - 1}")
        raise ValueError(f"{name}: the bytes of its {what} are not the ones {where} follows "
                         f"(SHA-256 {sha[:16]}..., the checkpoint's {d['sha256'][:16]}...): "
                         "the file was changed")
    last = dict(d["last"]["step"])
    last.update({c: a.copy() for c, a in d["last"]["particle"].items()})
    hist.rows = [last]
    mine = hist.wide_lines().rstrip("\n").encode().split(b",")
    theirs = raw[cut:ends[k]].split(b",")
    if theirs[1:] != mine[1:]:  # the time may have moved to a resumed run's clock
        raise ValueError(f"{name}: row {k} is not the last row {where} follows (values other "
                         "than t differ): the file was changed")
    values = np.zeros((0, len(mine)))
    if k > 1:
        try:
            values = np.loadtxt(io.StringIO(raw[len(head):cut].decode()), delimiter=",",
                                dtype=np.float64, ndmin=2)
        except ValueError as exc:
            raise ValueError(f"{name}: rows 1-{k - 1}: not a table of numbers "
                             f"({' '.join(str(exc).split())})") from None
    rows = hist.rows_from_wide(values)
    for c, v in d["last"]["step"].items():  # ints stay ints (the iteration counts)
        if isinstance(v, int):
            for r in rows:
                if float(r[c]).is_integer():
                    r[c] = int(r[c])
    rows.append(last)
    return rows


# ---------------------------------------------------------------------- write
def save(sim, k: int, series) -> Path:
    """Write ``checkpoint.npz`` into the simulation's output directory after step ``k``.

    The history rows stay in ``history.csv`` (the run's live file, synced here if
    it lags behind; :class:`~skfem_granular.simulation.Simulation` syncs it at every
    checkpoint); the checkpoint keeps their number, their digest and the last row.
    The checkpoint written before (if any) is kept as ``checkpoint.prev.npz`` once
    the new one is complete.

    Raises
    ------
    ValueError
        When the history does not have ``k`` rows.
    """
    if len(sim.history) != k:
        raise ValueError(f"k = {k}: the history has {len(sim.history)} rows (a checkpoint "
                         "follows all of them)")
    content = {
        "scene": sim.scene,
        "k": int(k),
        "dem": sim.dem.save_state(),
        "stepper": sim.stepper.checkpoint_state(),
        "history": {"rows": int(k), "sha256": _history_digest(sim, k),
                    "last": _last_row(sim.history, k)},
        "frames": {name: [(float(t), str(f)) for t, f in s.frames]
                   for name, s in (series or {}).items() if s is not None},
    }
    # the run that writes a checkpoint goes on as a run resumed from it would (bit for bit)
    sim.stepper.forget_caches()
    from .. import __version__

    node, arrays = plain.encode(content, REGISTRY)
    header = {"format": FORMAT, "version": VERSION, "written_by": f"skfem-granular {__version__}",
              "content": node}
    out = Path(sim.output_dir)
    return plain.write(out / FILENAME, header, arrays, fsync=True, keep=out / PREVIOUS_FILENAME)


def promote(directory, path) -> bool:
    """Make the checkpoint at ``path`` the newest (``checkpoint.npz``) too; whether it changed.

    A run resumed from ``checkpoint.prev.npz`` (the newest could not be used) calls it
    when it rewrites the history, so that its next checkpoint keeps a good one as the
    previous.
    """
    d, path = Path(directory), Path(path)
    if path.name == FILENAME:
        return False
    return keep_previous(path, d / FILENAME, fsync=True)


# ---------------------------------------------------------------------- read
def load(directory) -> dict:
    """Read and validate the newest usable checkpoint in ``directory``, with its history.

    ``checkpoint.npz`` is read; when it is absent, cannot be read or does not fit
    ``history.csv``, ``checkpoint.prev.npz`` is (and ``warning`` says why).

    Returns
    -------
    dict
        ``scene`` (a validated :class:`~skfem_granular.scene.Scene`), ``k`` (steps
        done), ``dem`` (:meth:`DEMSystem.save_state` dict), ``stepper``
        (``checkpoint_state()`` dict), ``history`` (the rows, read back from
        ``history.csv``), ``frames`` (``{series: [(t, file), ...]}``), ``path`` (the
        file read), ``version`` and ``warning`` (one line, or None).

    Raises
    ------
    ValueError
        One line naming the file and the field: no checkpoint, a pickle
        checkpoint of an earlier version, a file of another format or version,
        unknown or missing keys, fields or arrays, wrong dtypes or shapes,
        NaN/inf, values a scene would refuse; a history file that is missing,
        shorter than the checkpoint's rows or changed. When both checkpoints
        fail, the newest's reason.
    """
    d = Path(directory)
    newest, previous = d / FILENAME, d / PREVIOUS_FILENAME
    if not newest.is_file() and not previous.is_file():
        if (d / LEGACY_FILENAME).is_file():
            raise ValueError(f"resume: {str(d / LEGACY_FILENAME)!r}: a pickle file, not loaded "
                             "(a checkpoint of an earlier version; loading it could run code "
                             "from the file): run again with this version to get a "
                             "checkpoint.npz")
        raise ValueError(f"resume: no {FILENAME} in {str(directory)!r} ({_why_none(d)})")
    if not newest.is_file():
        data = _load(previous)
        data["warning"] = (f"resume: no {FILENAME} in {str(d)!r}: resuming from "
                           f"{PREVIOUS_FILENAME} (step {data['k']})")
        return data
    try:
        return _load(newest)
    except ValueError as exc:
        if not previous.is_file():
            raise
        try:
            data = _load(previous)
        except ValueError:
            raise exc from None
        reason = " ".join(str(exc).split())
        data["warning"] = f"{reason}; resuming from {PREVIOUS_FILENAME} (step {data['k']})"
        return data


def _load(path: Path) -> dict:
    """One checkpoint file, validated, with its history rows."""
    where = f"checkpoint {str(path)!r}"
    header, arrays = plain.read(path, where=where)
    extra = sorted(set(header) - HEADER_KEYS)
    if extra:
        raise ValueError(f"{where}: header: unknown key {extra[0]!r}")
    if header.get("format") != FORMAT:
        raise ValueError(f"{where}: format = {header.get('format')!r}: not a {FORMAT!r} file")
    version = header.get("version")
    if version not in READ_VERSIONS or isinstance(version, bool):
        raise ValueError(f"{where}: version = {version!r}: this version of skfem-granular "
                         f"reads checkpoint versions {' and '.join(map(str, READ_VERSIONS))} "
                         "only")
    missing = sorted(HEADER_KEYS - set(header))
    if missing:
        raise ValueError(f"{where}: header: missing key {missing[0]!r}")
    data = plain.decode(header["content"], arrays, REGISTRY, where=where,
                        nonfinite_ok=_nonfinite_ok)
    if not isinstance(data, dict):
        raise ValueError(f"{where}: content: must be a dict")
    extra, missing = sorted(set(data) - CONTENT_KEYS), sorted(CONTENT_KEYS - set(data))
    if extra:
        raise ValueError(f"{where}: {extra[0]}: unknown key (a checkpoint holds "
                         f"{', '.join(sorted(CONTENT_KEYS))})")
    if missing:
        raise ValueError(f"{where}: {missing[0]}: missing")
    scene = data["scene"]
    if not isinstance(scene, Scene):
        raise ValueError(f"{where}: scene: must be a Scene, got {type(scene).__name__}")
    K = len(scene.particles)
    if version == 3:
        data["history"] = _history_rows(data["history"], where, K)
        rows = len(data["history"])
    else:
        _check_history(data["history"], where, K)
        rows = data["history"]["rows"]
    _check(data, where, K, rows)
    if version != 3:  # last: the file is read only once the checkpoint itself is good
        data["history"] = _history_from_file(path.parent, data["history"], K, where)
    data.update(path=path, version=version, warning=None)
    return data


def _why_none(d: Path) -> str:
    """Why a folder has no checkpoint, for the one line that says so."""
    from ..io import partial_files
    from .folder import run_files

    if any(p.name.startswith(".partial-checkpoint") for p in partial_files(d)):
        return ("the run was killed while writing its first checkpoint; start it again "
                "with --overwrite")
    if run_files(d):
        return ("the run there wrote none: checkpoints come every output.checkpoint_every "
                "steps and when SIGINT/SIGTERM stop a run; start it again with --overwrite")
    return "no run's output there: run with output.checkpoint_every > 0 first"


def _fail(where, path, problem):
    raise ValueError(f"{where}: {path}: {problem}")


def _check_array(where, path, a, shape, *, none=False, dtype=np.float64):
    if a is None and none:
        return
    if not isinstance(a, np.ndarray):
        _fail(where, path, f"must be an array{' or None' if none else ''}, got "
                           f"{type(a).__name__}")
    if a.dtype != dtype:
        _fail(where, path, f"dtype {a.dtype}: must be {np.dtype(dtype)}")
    if a.shape != tuple(shape):
        _fail(where, path, f"shape {a.shape}: must be {tuple(shape)}")


def _check_count(where, path, v):
    if not (isinstance(v, int) and not isinstance(v, bool) and v >= 0):
        _fail(where, path, f"= {v!r}: must be an integer >= 0")


def _check_time(where, path, v, *, none=False):
    if v is None and none:
        return
    if isinstance(v, np.ndarray) and v.shape == () and v.dtype == np.float64:
        v = float(v)  # the DEM's BDF2 history keeps its step as a 0-d array
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) or v < 0:
        _fail(where, path, f"= {v!r}: must be a finite number >= 0")


def _check(data, where, K, rows):
    """Shapes and ranges of the fields this version knows (fields it does not know pass)."""
    _check_count(where, "k", data["k"])
    if data["k"] != rows:
        _fail(where, "k", f"= {data['k']}: must equal the number of history rows ({rows})")
    _check_dem(data["dem"], where, K)
    _check_stepper(data["stepper"], where, K)
    _check_frames(data["frames"], where)


def _check_dem(dem, where, K):
    """The DEM state's arrays against the number of particles."""
    if not isinstance(dem, dict):
        _fail(where, "dem", "must be a dict")
    for name, shape in (("q", (3, K)), ("v", (3, K)), ("external_force", (2, K)),
                        ("external_torque", (K,))):
        if name in dem:
            _check_array(where, f"dem.{name}", dem[name], shape)
    if "t" in dem:
        _check_time(where, "dem.t", dem["t"])
    if "steps" in dem:
        _check_count(where, "dem.steps", dem["steps"])
    if "contact_keys" in dem and "contact_ft" in dem:
        keys = dem["contact_keys"]
        _check_array(where, "dem.contact_keys", keys, getattr(keys, "shape", ()),
                     dtype=np.int64)
        _check_array(where, "dem.contact_ft", dem["contact_ft"], keys.shape)
    bdf2 = dem.get("bdf2")
    if isinstance(bdf2, dict):
        for name in ("q_prev", "v_prev", "a", "a_prev"):
            if name in bdf2:
                _check_array(where, f"dem.bdf2.{name}", bdf2[name], (3, K), none=True)
        if "dt_prev" in bdf2:
            _check_time(where, "dem.bdf2.dt_prev", bdf2["dt_prev"], none=True)


def _check_stepper(st, where, K):
    """The stepper's state: the mesh, the fluid and particle histories."""
    if not isinstance(st, dict):
        _fail(where, "stepper", "must be a dict")
    if "steps_taken" in st:
        _check_count(where, "stepper.steps_taken", st["steps_taken"])
    for name, v in (st.get("counters") or {}).items():
        _check_count(where, f"stepper.counters.{name}", v)
    for name, shape in (("mesh_centers", (2, K)), ("mesh_angles", (K,)),
                        ("coupling_centers", (2, K))):
        if name in st:
            _check_array(where, f"stepper.{name}", st[name], shape)
    mesh = st.get("mesh")
    fitted = mesh if isinstance(mesh, meshing.BodyFittedMesh) else None
    m = fitted.mesh if fitted is not None else mesh
    if "mesh" in st and not isinstance(m, skfem.MeshTri):
        _fail(where, "stepper.mesh", f"must be a mesh, got {type(mesh).__name__}")
    if fitted is not None:
        nodes = fitted.particle_nodes
        if len(nodes) != K:
            _fail(where, "stepper.mesh.particle_nodes", f"{len(nodes)} outlines: must be {K}")
        for i, idx in enumerate(nodes):
            if idx.ndim != 1 or idx.dtype.kind != "i" or (
                    idx.size and (idx.min() < 0 or idx.max() >= m.p.shape[1])):
                _fail(where, f"stepper.mesh.particle_nodes[{i}]",
                      f"must be vertex indices in [0, {m.p.shape[1]})")
        if fitted.recipe is not None and len(fitted.recipe.particles) != K:
            _fail(where, "stepper.mesh.recipe.particles",
                  f"{len(fitted.recipe.particles)} outlines: must be {K}")
    state = st.get("state")
    if "state" in st and not isinstance(state, CoupledState):
        _fail(where, "stepper.state", f"must be a CoupledState, got {type(state).__name__}")
    if state is not None and m is not None:
        nv, ne = m.p.shape[1], m.facets.shape[1]
        nu = 2 * (nv + ne)
        fluid = {"u_n": (nu,), "p_n": (nv,), "x": (nu + nv,), "u_prev": (nu,), "du_n": (nu,),
                 "du_prev": (nu,)}
        rigid = {"xi_prev": (3, K), "q_prev": (3, K), "dxi_n": (3, K), "dxi_prev": (3, K),
                 "F_held": (2, K), "T_held": (K,)}
        moving = {"nodes_n": (2, nv), "nodes_prev": (2, nv)}  # ALE: the vertices at t, t_{n-1}
        for name, shape in {**fluid, **rigid, **moving}.items():
            if hasattr(state, name):
                none = name not in ("u_n", "x")
                _check_array(where, f"stepper.state.{name}", getattr(state, name), shape,
                             none=none)
        for name in ("t",):
            _check_time(where, f"stepper.state.{name}", getattr(state, name, 0.0))
        for name in ("dt_prev", "dt_next"):
            if hasattr(state, name):
                _check_time(where, f"stepper.state.{name}", getattr(state, name), none=True)
        for name in ("since_remesh", "contact_age"):
            if hasattr(state, name):
                _check_count(where, f"stepper.state.{name}", getattr(state, name))


def _check_frames(frames, where):
    """The frames written so far: ``(t, file)`` of the known series."""
    if not isinstance(frames, dict):
        _fail(where, "frames", "must be a dict")
    for name, lst in frames.items():
        if name not in ("flow", "particles"):
            _fail(where, f"frames.{name}", "unknown series (flow, particles)")
        pattern = re.compile(rf"^{name}_\d{{5}}\.vtu$")
        if not isinstance(lst, list):
            _fail(where, f"frames.{name}", "must be a list of (t, file)")
        for i, fr in enumerate(lst):
            ok = (isinstance(fr, tuple) and len(fr) == 2 and isinstance(fr[1], str)
                  and pattern.match(fr[1]) and not isinstance(fr[0], bool)
                  and isinstance(fr[0], (int, float)))
            if not ok:
                _fail(where, f"frames.{name}[{i}]", f"= {fr!r}: must be (t, '{name}_NNNNN.vtu')")


def check_entries(saved, template, path: str, where: str = "checkpoint") -> None:
    """Refuse dict keys in ``saved`` that ``template`` (a fresh object's state) lacks, and back.

    ``template`` is what this version's stepper or DEM hands over
    (``checkpoint_state()``, ``save_state()``), so an entry added to them later is
    expected with no change here.
    """
    if isinstance(template, dict):
        if not isinstance(saved, dict):
            _fail(where, path, f"must be a dict, got {type(saved).__name__}")
        extra = sorted(set(saved) - set(template))
        if extra:
            _fail(where, f"{path}.{extra[0]}", "unknown key (this version does not have it)")
        missing = sorted(set(template) - set(saved))
        if missing:
            _fail(where, f"{path}.{missing[0]}", "missing")
        for k in template:
            check_entries(saved[k], template[k], f"{path}.{k}", where)
    elif dataclasses.is_dataclass(template) and not isinstance(template, type):
        if type(saved) is not type(template):
            _fail(where, path, f"must be a {type(template).__name__}, got "
                               f"{type(saved).__name__}")
