"""Plain-data files: nested Python values as numpy arrays plus a JSON header, read back strictly.

A value is a tree of ``None``, ``bool``, ``int``, ``float``, ``str``, lists,
tuples, dicts with string keys, numpy arrays and numpy scalars, and objects
of an *allowlisted* set of types (a :class:`Registry`: dataclasses by their
qualified names, and a few other types through a :class:`Custom` codec).
:func:`encode` turns such a tree into a JSON-able header and a dict of arrays;
:func:`write` (:mod:`.npz`) stores both in one ``.npz`` file (a zip: ``header.json`` and one
``.npy`` member per array, written atomically); :func:`read` and
:func:`decode` reverse it and refuse anything that does not fit:

- an unknown format name or version, a JSON object with unknown or missing
  keys, a type that is not in the registry, a dataclass with an unknown or a
  missing field;
- an array whose dtype is not float64, int64, int32 or bool, whose shape differs
  from the header's, that the header does not mention, or that is not finite
  where finite values are required (everywhere unless the caller allows
  otherwise for a field, or the dataclass field's default is itself NaN/inf).

Each refusal is a :class:`ValueError` of one line naming the field, e.g.
``"checkpoint 'out/checkpoint.npz': stepper.state.u_n: contains NaN or inf
(must be finite)"``. Nothing here ever unpickles: arrays are read with
``allow_pickle=False`` and objects are rebuilt only from allowlisted types,
through their constructors (so a dataclass's ``__post_init__`` validates it).

Header nodes: JSON scalars for ``None``, ``bool``, ``int``, finite ``float``
and ``str``; JSON lists for lists; and objects with exactly one tag key:
``{"$float": "nan"}``, ``{"$tuple": [...]}``, ``{"$dict": {...}}``,
``{"$numpy": "float64", "value": ...}``, ``{"$array": key, "dtype": ...,
"shape": [...]}``, ``{"$object": qualified name, "fields": {...}}``.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Callable, Iterable
from typing import Any, NoReturn

import numpy as np

from .npz import HEADER_MEMBER, MEMORY_DTYPES, STORED_DTYPES, read, write

__all__ = ["HEADER_MEMBER", "MEMORY_DTYPES", "STORED_DTYPES", "Custom", "Registry", "decode",
           "encode", "qualified_name", "read", "write"]

#: numpy scalar types a value may be
SCALAR_TYPES = {"float64": np.float64, "int64": np.int64, "int32": np.int32, "bool": np.bool_}

_TAGS = {
    "$float": {"$float"},
    "$tuple": {"$tuple"},
    "$dict": {"$dict"},
    "$numpy": {"$numpy", "value"},
    "$array": {"$array", "dtype", "shape"},
    "$object": {"$object", "fields"},
}
_NONFINITE = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf}
_KEY_CHARS = re.compile(r"[^A-Za-z0-9_.\[\]-]")


def qualified_name(cls: type) -> str:
    """``module.QualName`` of a class, as the header names it."""
    return f"{cls.__module__}.{cls.__qualname__}"


@dataclasses.dataclass(frozen=True)
class Custom:
    """How to store an allowlisted type that is not a dataclass (or not as its fields).

    Attributes
    ----------
    cls : type
        The type (instances of exactly this type are stored this way).
    fields : tuple of str
        The names :attr:`to_fields` returns and :attr:`from_fields` takes.
    to_fields : callable
        ``to_fields(obj) -> dict`` of plain values.
    from_fields : callable
        ``from_fields(dict) -> obj``; may raise ``ValueError`` for bad values.
    name : str, optional
        The name in the header (default: the qualified name of ``cls``).
    """

    cls: type
    fields: tuple
    to_fields: Callable
    from_fields: Callable
    name: str | None = None

    @property
    def key(self) -> str:
        return self.name or qualified_name(self.cls)


class Registry:
    """The types a file may hold besides plain values.

    Parameters
    ----------
    dataclasses : iterable of type
        Dataclasses stored as their ``init`` fields and rebuilt as
        ``cls(**fields)``; a field added to one of them later is stored too,
        with no change here, and read at its default from a file written before it when
        the class names it in ``LATER_FIELDS`` (a class attribute); a field it held once
        and names in ``DROPPED_FIELDS`` is ignored in a file that has it.
    custom : iterable of Custom
        Other types, with their own codecs.
    """

    def __init__(self, dataclasses: Iterable[type] = (), custom: Iterable[Custom] = ()):
        self._encoders: dict[type, tuple[str, Callable]] = {}
        # name -> (build from a dict of fields, field names (None: a dataclass's), dataclass)
        self._decoders: dict[str, tuple[Callable[[dict], Any], tuple[str, ...] | None,
                                        type | None]] = {}
        for cls in dataclasses:
            self.add_dataclass(cls)
        for c in custom:
            self.add_custom(c)

    def add_dataclass(self, cls: type) -> None:
        """Allow the dataclass ``cls``."""
        if not dataclasses.is_dataclass(cls):
            raise TypeError(f"{qualified_name(cls)} is not a dataclass")
        name = qualified_name(cls)

        def to_fields(obj):
            return {f.name: getattr(obj, f.name) for f in dataclasses.fields(obj) if f.init}

        self._encoders[cls] = (name, to_fields)
        self._decoders[name] = (lambda kw: cls(**kw), None, cls)

    def add_custom(self, c: Custom) -> None:
        """Allow a type with its own codec."""
        self._encoders[c.cls] = (c.key, c.to_fields)
        self._decoders[c.key] = (c.from_fields, tuple(c.fields), None)

    def names(self) -> list[str]:
        """The type names the header may use."""
        return sorted(self._decoders)

    def encoder(self, obj):
        return self._encoders.get(type(obj))

    def decoder(self, name: str):
        """``(build, field names, dataclass or None)`` for a type name, or None."""
        entry = self._decoders.get(name)
        if entry is None:
            return None
        build, names, cls = entry
        if cls is not None:
            names = tuple(f.name for f in dataclasses.fields(cls) if f.init)
        return build, names, cls


def _nonfinite_default(cls: type, name: str) -> bool:
    """Whether the dataclass field ``name`` defaults to a NaN or infinite float."""
    for f in dataclasses.fields(cls):
        if f.name == name:
            d = f.default
            return isinstance(d, float) and not math.isfinite(d)
    return False


def _join(path: str, name) -> str:
    if isinstance(name, int):
        return f"{path}[{name}]"
    return f"{path}.{name}" if path else str(name)


# ---------------------------------------------------------------------- encode
def encode(value, registry: Registry, path: str = "") -> tuple[object, dict[str, np.ndarray]]:
    """A JSON-able header node for ``value`` and the arrays it refers to.

    Raises
    ------
    TypeError
        For a value of a type the format cannot hold (naming the field): a
        programming error, not bad input.
    """
    arrays: dict[str, np.ndarray] = {}
    node = _encode(value, registry, path, arrays)
    return node, arrays


def _array_key(path: str, arrays: dict) -> str:
    key = _KEY_CHARS.sub("_", path) or "array"
    base, n = key, 1
    while key in arrays or key == HEADER_MEMBER.removesuffix(".json"):
        n += 1
        key = f"{base}~{n}"
    return key


def _encode(v, reg: Registry, path: str, arrays: dict):
    if v is None or isinstance(v, (bool, str)):
        return v
    if isinstance(v, np.generic):
        name = v.dtype.name
        if name not in SCALAR_TYPES:
            raise TypeError(f"{path}: numpy scalar of dtype {name} cannot be stored "
                            f"(allowed: {', '.join(SCALAR_TYPES)})")
        return {"$numpy": name, "value": _encode(v.item(), reg, path, arrays)}
    if isinstance(v, int):
        return int(v)
    if isinstance(v, float):
        if math.isfinite(v):
            return float(v)
        return {"$float": "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")}
    if isinstance(v, np.ndarray):
        name = v.dtype.name
        if name not in MEMORY_DTYPES:
            raise TypeError(f"{path}: array of dtype {name} cannot be stored "
                            f"(allowed: {', '.join(MEMORY_DTYPES)})")
        key = _array_key(path, arrays)
        arrays[key] = v.astype(MEMORY_DTYPES[name], copy=False)
        return {"$array": key, "dtype": name, "shape": list(v.shape)}
    if isinstance(v, list):
        return [_encode(x, reg, _join(path, i), arrays) for i, x in enumerate(v)]
    if isinstance(v, tuple) and type(v) is tuple:
        return {"$tuple": [_encode(x, reg, _join(path, i), arrays) for i, x in enumerate(v)]}
    if type(v) is dict:
        bad = [k for k in v if not isinstance(k, str)]
        if bad:
            raise TypeError(f"{path}: dict keys must be strings, got {bad[0]!r}")
        return {"$dict": {k: _encode(x, reg, _join(path, k), arrays) for k, x in v.items()}}
    enc = reg.encoder(v)
    if enc is None:
        raise TypeError(f"{path}: a {qualified_name(type(v))} cannot be stored (allowed types: "
                        f"{', '.join(reg.names())}, plain values and arrays)")
    name, to_fields = enc
    fields = to_fields(v)
    return {"$object": name,
            "fields": {k: _encode(x, reg, _join(path, k), arrays) for k, x in fields.items()}}


# ---------------------------------------------------------------------- decode
class _Reader:
    def __init__(self, arrays: dict, reg: Registry, where: str, nonfinite_ok: Callable):
        self.arrays = arrays
        self.reg = reg
        self.where = where
        self.nonfinite_ok = nonfinite_ok
        self.used: set[str] = set()

    def fail(self, path: str, problem: str) -> NoReturn:
        raise ValueError(f"{self.where}: {path or '(top)'}: {problem}")

    def keys(self, path: str, node: dict, expected: set):
        got = set(node)
        if got != expected:
            extra, missing = sorted(got - expected), sorted(expected - got)
            if extra:
                self.fail(path, f"unknown key {extra[0]!r} (expected "
                                f"{', '.join(sorted(expected))})")
            self.fail(path, f"missing key {missing[0]!r}")

    def node(self, n, path: str, finite_default: bool = False):
        if n is None or isinstance(n, (bool, str)):
            return n
        if isinstance(n, int):
            return n
        if isinstance(n, float):
            if not (math.isfinite(n) or finite_default or self.nonfinite_ok(path)):
                self.fail(path, f"= {n}: must be a finite number")
            return n
        if isinstance(n, list):
            return [self.node(x, _join(path, i)) for i, x in enumerate(n)]
        if not isinstance(n, dict):
            self.fail(path, f"unreadable value {n!r}")
        tags = [k for k in n if k in _TAGS]
        if len(tags) != 1:
            self.fail(path, f"unknown entry with keys {sorted(n)} (expected one of "
                            f"{', '.join(sorted(_TAGS))})")
        tag = tags[0]
        self.keys(path, n, _TAGS[tag])
        if tag == "$float":
            if not isinstance(n["$float"], str) or n["$float"] not in _NONFINITE:
                self.fail(path, f"$float = {n['$float']!r}: must be 'nan', 'inf' or '-inf'")
            if not (finite_default or self.nonfinite_ok(path)):
                self.fail(path, f"= {n['$float']}: must be a finite number")
            return _NONFINITE[n["$float"]]
        if tag == "$tuple":
            items = n["$tuple"]
            if not isinstance(items, list):
                self.fail(path, "$tuple: must be a list")
            return tuple(self.node(x, _join(path, i)) for i, x in enumerate(items))
        if tag == "$dict":
            d = n["$dict"]
            if not isinstance(d, dict):
                self.fail(path, "$dict: must be an object")
            return {k: self.node(x, _join(path, k)) for k, x in d.items()}
        if tag == "$numpy":
            name = n["$numpy"]
            if not isinstance(name, str) or name not in SCALAR_TYPES:
                self.fail(path, f"numpy scalar type {name!r}: must be one of "
                                f"{', '.join(SCALAR_TYPES)}")
            v = self.node(n["value"], path, finite_default)
            ok = (isinstance(v, bool) if name == "bool"
                  else isinstance(v, int) and not isinstance(v, bool) if name.startswith("int")
                  else isinstance(v, (int, float)) and not isinstance(v, bool))
            if not ok:
                self.fail(path, f"value {v!r} is not a {name}")
            try:
                return SCALAR_TYPES[name](v)
            except OverflowError:
                self.fail(path, f"value {v!r} does not fit a {name}")
        if tag == "$array":
            return self.array(n, path, finite_default)
        return self.obj(n, path)

    def array(self, n: dict, path: str, finite_default: bool):
        key, dtype, shape = n["$array"], n["dtype"], n["shape"]
        if not isinstance(key, str) or key not in self.arrays:
            self.fail(path, f"array {key!r} is not in the file")
        if key in self.used:
            self.fail(path, f"array {key!r} is named twice in the header")
        if not isinstance(dtype, str) or dtype not in MEMORY_DTYPES:
            self.fail(path, f"dtype {dtype!r}: must be one of {', '.join(MEMORY_DTYPES)}")
        if not (isinstance(shape, list)
                and all(isinstance(s, int) and not isinstance(s, bool) and s >= 0
                        for s in shape)):
            self.fail(path, f"shape {shape!r}: must be a list of integers >= 0")
        a = self.arrays[key]
        self.used.add(key)
        stored = ("int32", "int64") if dtype == "int32" else (MEMORY_DTYPES[dtype],)
        if a.dtype.name not in stored:
            self.fail(path, f"array of dtype {a.dtype.name} in the file: must be "
                            f"{' or '.join(stored)} (header: {dtype})")
        if list(a.shape) != shape:
            self.fail(path, f"array of shape {tuple(a.shape)} in the file, {tuple(shape)} in "
                            "the header")
        if dtype == "float64" and not (finite_default or self.nonfinite_ok(path)):
            if not np.all(np.isfinite(a)):
                self.fail(path, "contains NaN or inf (must be finite)")
        if dtype == "int32":
            info = np.iinfo(np.int32)
            if a.size and (a.min() < info.min or a.max() > info.max):
                self.fail(path, "values out of the int32 range")
        return a.astype(dtype, copy=False)

    def obj(self, n: dict, path: str):
        name, fields = n["$object"], n["fields"]
        dec = self.reg.decoder(name) if isinstance(name, str) else None
        if dec is None:
            self.fail(path, f"type {name!r} is not one this file may hold (allowed: "
                            f"{', '.join(self.reg.names())})")
        build, names, cls = dec
        if not isinstance(fields, dict):
            self.fail(path, "fields: must be an object")
        dropped = getattr(cls, "DROPPED_FIELDS", ())  # held once: ignored
        extra = [k for k in fields if k not in names and k not in dropped]
        if extra:
            self.fail(_join(path, extra[0]), f"unknown field of {name}")
        later = getattr(cls, "LATER_FIELDS", ())  # added since: their defaults if absent
        missing = [k for k in names if k not in fields and k not in later]
        if missing:
            self.fail(_join(path, missing[0]), f"missing field of {name}")
        for k in (k for k in dropped if k in fields):  # read (checked, counted), not kept
            self.node(fields[k], _join(path, k), True)
        kw = {}
        for k in (k for k in names if k in fields):
            nf = cls is not None and _nonfinite_default(cls, k)
            kw[k] = self.node(fields[k], _join(path, k), nf)
        try:
            return build(kw)
        except (ValueError, TypeError) as exc:
            self.fail(path, " ".join(str(exc).split()))


def decode(node, arrays: dict, registry: Registry, *, where: str = "file",
           nonfinite_ok: Callable[[str], bool] = lambda path: False, path: str = ""):
    """The value :func:`encode` made ``node`` and ``arrays`` from, checked as it is rebuilt.

    Parameters
    ----------
    node : object
        The header node (parsed JSON).
    arrays : dict of ndarray
        The file's arrays by key; every one must be named by the header.
    registry : Registry
        The types that may be rebuilt.
    where : str
        Prefix of the error messages (e.g. the file name).
    nonfinite_ok : callable, optional
        ``nonfinite_ok(path) -> bool``: whether the float or float array at
        ``path`` may hold NaN or inf (default: nowhere, except dataclass fields
        whose default is NaN or inf).
    path : str
        The path of ``node`` in the error messages.

    Raises
    ------
    ValueError
        One line naming the field, for anything that does not fit.
    """
    r = _Reader(arrays, registry, where, nonfinite_ok)
    value = r.node(node, path)
    unused = sorted(set(arrays) - r.used)
    if unused:
        r.fail(unused[0], "array in the file that the header does not name")
    return value
