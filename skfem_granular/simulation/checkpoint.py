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
``history.csv`` a row at a time (``%.17g`` text: the same doubles; the particle
values of the newest rows only, as a running table keeps them,
:data:`skfem_granular.io.table.MEMORY_BYTES`), refuses a file that is shorter
or whose bytes differ (one line naming the file), and the resumed run cuts the
file after the checkpoint's rows. The last row is kept in the
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
from ..io import keep_previous, plain
from ..scene import Effects, MeshSpec, ParticleSpec, Scene, TimeSpec
from .checkpoint_checks import (  # noqa: F401 (check_entries: the resume's entry check)
    check_array,
    check_content,
    check_count,
    check_entries,
    fail,
)
from .checkpoint_history import (  # noqa: F401 (HISTORY_FILENAME: the file's name)
    HISTORY_FILENAME,
    check_history,
    history_digest,
    history_from_file,
    history_rows,
    last_row,
)

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
#: The pickle checkpoints of earlier versions: refused, never unpickled.
LEGACY_FILENAME = "checkpoint.pkl"

HEADER_KEYS = {"format", "version", "written_by", "content"}
#: A checkpoint's content (``history``: version 3 the rows, version 4 how many, their
#: digest and the last).
CONTENT_KEYS = {"scene", "k", "dem", "stepper", "history", "frames"}


def _polygon(d):
    return Polygon(d["vertices"], name="polygon")


def _mesh_fields(m):
    # stored as int32 (half the bytes; read back as int32 anyway)
    return {"doflocs": m.doflocs, "t": m.t.astype(np.int32, copy=False),
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
        "history": {"rows": int(k), "sha256": history_digest(sim, k),
                    "last": last_row(sim.history, k)},
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
        data["history"] = history_rows(data["history"], where, K)
        rows = len(data["history"])
    else:
        check_history(data["history"], where, K)
        rows = data["history"]["rows"]
    check_content(data, where, K, rows)
    if version != 3:  # last: the file is read only once the checkpoint itself is good
        data["history"] = history_from_file(path.parent, data["history"], K, where)
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
