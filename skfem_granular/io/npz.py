"""The container of plain-data files: a zip of ``header.json`` and ``.npy`` arrays.

:func:`write` stores a JSON header and arrays in one ``.npz`` file, each
member uncompressed, atomically; :func:`read` reads them back without pickle
and without inflating anything beyond what the header declares (see
:func:`read`). :mod:`.plain` builds the header and the arrays from values and
back.
"""

from __future__ import annotations

import json
import math
import zipfile
from pathlib import Path

import numpy as np

from .files import atomic_write

#: dtypes an array may have in the file
STORED_DTYPES = ("float64", "int64", "int32", "bool")
#: dtypes an array may have in memory, and how each is stored (files written before int32
#: was stored as such hold int32 arrays as int64: still read)
MEMORY_DTYPES = {"float64": "float64", "int64": "int64", "bool": "bool", "int32": "int32"}
HEADER_MEMBER = "header.json"
#: Largest header read (bytes; a checkpoint's is about 7 kB).
MAX_HEADER_BYTES = 16_000_000
#: Deepest nesting of a header (a checkpoint's is 13 levels).
MAX_DEPTH = 64


def _member(name: str) -> zipfile.ZipInfo:
    """A stored member dated 1980-01-01: the same content gives the same file bytes
    (a member dated by the clock made two equal checkpoints differ when their writes
    fell into different seconds)."""
    info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))
    info.compress_type = zipfile.ZIP_STORED
    return info


def write(path, header: dict, arrays: dict[str, np.ndarray], *, fsync: bool = False,
          keep=None) -> Path:
    """Write ``header`` (JSON) and ``arrays`` (``.npy`` members) as one zip, atomically.

    ``fsync`` and ``keep`` (the file ``path`` held until now kept under that name, once
    the new one is complete) as for :func:`~skfem_granular.io.files.atomic_path`.
    """
    text = json.dumps(header, allow_nan=False, separators=(",", ":")).encode()
    for key, a in arrays.items():
        if a.dtype.name not in STORED_DTYPES:
            raise TypeError(f"{key}: array of dtype {a.dtype.name} cannot be stored")

    def save(tmp):
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_STORED, allowZip64=True) as zf:
            zf.writestr(_member(HEADER_MEMBER), text)
            for key, a in arrays.items():
                with zf.open(_member(f"{key}.npy"), "w", force_zip64=True) as f:
                    np.lib.format.write_array(f, np.asanyarray(a), allow_pickle=False)

    return atomic_write(path, save, fsync=fsync, keep=keep)


def read(path, *, where: str | None = None) -> tuple[dict, dict[str, np.ndarray]]:
    """The header and the arrays of a file :func:`write` wrote (no pickle, ever).

    Nothing is inflated beyond what the header declares: the header may be at most
    :data:`MAX_HEADER_BYTES` and :data:`MAX_DEPTH` levels deep; every member must be
    stored uncompressed (as :func:`write` stores them, so a member takes in memory
    what it takes on the disk) and be exactly the ``.npy`` array the header
    declares (key, dtype, shape) before its data is read.

    Raises
    ------
    ValueError
        One line, for a file that is not such a zip, a header that is not JSON or
        too large or too deep, or a member that is not a plain ``.npy`` array of the
        declared shape.
    """
    path = Path(path)
    where = where or f"{str(path)!r}"
    try:
        zf = zipfile.ZipFile(path)
    except FileNotFoundError:
        raise ValueError(f"{where}: not found") from None
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
        raise ValueError(f"{where}: not a readable file of this format "
                         f"({type(exc).__name__}: {' '.join(str(exc).split())})") from None
    with zf:
        header = _read_header(zf, where)
        declared = _declared_arrays(header, where)
        arrays = {}
        for info in zf.infolist():
            if info.filename == HEADER_MEMBER:
                continue
            if not info.filename.endswith(".npy"):
                raise ValueError(f"{where}: {info.filename}: unexpected member (only "
                                 f"{HEADER_MEMBER} and .npy arrays)")
            key = info.filename.removesuffix(".npy")
            arrays[key] = _read_member(zf, info, key, declared, where)
    return header, arrays


def _read_header(zf: zipfile.ZipFile, where: str) -> dict:
    try:
        info = zf.getinfo(HEADER_MEMBER)
    except KeyError:
        raise ValueError(f"{where}: no {HEADER_MEMBER} in the file") from None
    if info.compress_type != zipfile.ZIP_STORED or info.file_size > MAX_HEADER_BYTES:
        raise ValueError(f"{where}: {HEADER_MEMBER}: {info.file_size} bytes"
                         f"{', compressed' if info.compress_type != zipfile.ZIP_STORED else ''}"
                         f": must be stored uncompressed, at most {MAX_HEADER_BYTES} bytes")
    try:
        raw = zf.read(HEADER_MEMBER)
        header = json.loads(raw.decode("utf-8"), parse_constant=_refuse_constant)
    except RecursionError:
        raise ValueError(f"{where}: {HEADER_MEMBER}: nested deeper than {MAX_DEPTH} "
                         "levels") from None
    except (ValueError, UnicodeDecodeError, zipfile.BadZipFile, OSError) as exc:
        raise ValueError(f"{where}: {HEADER_MEMBER} is not valid JSON "
                         f"({' '.join(str(exc).split())})") from None
    if not isinstance(header, dict):
        raise ValueError(f"{where}: {HEADER_MEMBER} must hold a JSON object")
    return header


def _declared_arrays(header: dict, where: str) -> dict[str, tuple]:
    """``{key: (dtype, shape)}`` of the header's ``$array`` nodes; refuses a deep header."""
    found: dict[str, tuple] = {}
    todo = [(header, 0)]
    while todo:
        node, depth = todo.pop()
        if depth > MAX_DEPTH:
            raise ValueError(f"{where}: {HEADER_MEMBER}: nested deeper than {MAX_DEPTH} levels")
        if isinstance(node, list):
            todo.extend((x, depth + 1) for x in node)
        elif isinstance(node, dict):
            key, shape = node.get("$array"), node.get("shape")
            if isinstance(key, str) and isinstance(shape, list) and all(
                    isinstance(n, int) and not isinstance(n, bool) and n >= 0 for n in shape):
                dtype = node.get("dtype")
                found.setdefault(key, (MEMORY_DTYPES.get(dtype) if isinstance(dtype, str)
                                       else None, tuple(shape)))
            todo.extend((x, depth + 1) for x in node.values())
    return found


def _read_member(zf: zipfile.ZipFile, info: zipfile.ZipInfo, key: str, declared: dict,
                 where: str) -> np.ndarray:
    """One ``.npy`` member, read only once it is known to be the array the header declares."""
    if info.compress_type != zipfile.ZIP_STORED:
        raise ValueError(f"{where}: {key}: compressed member ({info.file_size} bytes "
                         "inflated): arrays must be stored uncompressed")
    fmt = np.lib.format
    try:
        with zf.open(info) as f:
            version = fmt.read_magic(f)
            read_header = fmt.read_array_header_1_0 if version == (1, 0) else \
                fmt.read_array_header_2_0
            shape, fortran, dtype = read_header(f)
            offset = f.tell()
    except Exception as exc:  # not an .npy member
        raise ValueError(f"{where}: {key}: not a plain array "
                         f"({' '.join(str(exc).split())})") from None
    if dtype.hasobject:
        raise ValueError(f"{where}: {key}: not a plain array (object arrays cannot be loaded "
                         "when allow_pickle=False)")
    if dtype.name not in STORED_DTYPES:
        raise ValueError(f"{where}: {key}: array of dtype {dtype.name}: must be one of "
                         f"{', '.join(STORED_DTYPES)}")
    if key not in declared:
        raise ValueError(f"{where}: {key}: array in the file that the header does not name")
    want_dtype, want_shape = declared[key]
    if tuple(shape) != want_shape:
        raise ValueError(f"{where}: {key}: array of shape {tuple(shape)} in the file, "
                         f"{want_shape} in the header")
    nbytes = math.prod(shape) * dtype.itemsize
    if info.file_size != offset + nbytes:
        raise ValueError(f"{where}: {key}: member of {info.file_size} bytes: the declared "
                         f"{dtype.name} array of shape {want_shape} takes {offset + nbytes}")
    try:
        with zf.open(info) as f:
            return fmt.read_array(f, allow_pickle=False)
    except Exception as exc:  # a corrupt member (CRC, truncated)
        raise ValueError(f"{where}: {key}: not a plain array "
                         f"({' '.join(str(exc).split())})") from None


def _refuse_constant(name):
    raise ValueError(f"{name} is not valid JSON (non-finite numbers are tagged)")
