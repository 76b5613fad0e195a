"""The TOML keys of a dataclass: a small table beside it, checked against its fields.

Each dataclass that a section of the scene file fills has a table
``{field name: KeyDoc or None}`` with one entry per field (``None``: the field
is not written in TOML). :func:`toml_keys` reads the class's fields
(:func:`dataclasses.fields`), refuses a table that misses a field or names one
that does not exist, and gives the section's keys with their defaults taken
from the fields themselves; the parser's accepted key sets and the scene-file
reference are both made from it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass


class _Required:
    """The default of a key that must be given."""

    def __repr__(self) -> str:
        return "REQUIRED"


#: The default of a key without one (the scene must give it).
REQUIRED = _Required()
#: ``KeyDoc.default`` when the key's default is its field's default.
FROM_FIELD = object()


@dataclass(frozen=True)
class KeyDoc:
    """What a TOML key is: its type, unit, allowed values and meaning.

    Attributes
    ----------
    type : str
        The TOML type, e.g. ``float``, ``[float, float]``, ``bool or "auto"``.
    meaning : str
        One line.
    allowed : str
        The allowed values, as the one-line error names them (``"> 0 and <= 1"``).
    unit : str
        SI unit, ``""`` for dimensionless values.
    key : str or None
        The TOML name when it is not the field's name.
    section : str or None
        The section, for a class whose fields spread over several (:class:`Scene`).
    default : object
        The key's default when it is not its field's (:data:`FROM_FIELD`), e.g. for
        keys that together make one field (a particle's ``sides``, ``radius``, ...).
    """

    type: str
    meaning: str
    allowed: str = "any"
    unit: str = ""
    key: str | None = None
    section: str | None = None
    default: object = FROM_FIELD


@dataclass(frozen=True)
class Key:
    """One key of a section: TOML name, the field it fills, its description and default."""

    name: str
    field: str
    doc: KeyDoc
    default: object


#: A table of a dataclass's TOML keys: ``{field name: KeyDoc, tuple of them, or None}``.
Docs = Mapping[str, "KeyDoc | tuple[KeyDoc, ...] | None"]


def field_default(f: dataclasses.Field) -> object:
    """A field's default (its factory called), :data:`REQUIRED` when it has none."""
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return REQUIRED


def check_table(cls: type, docs: Docs) -> None:
    """Refuse a table that misses a field of ``cls`` or names a field it does not have."""
    names = [f.name for f in dataclasses.fields(cls)]
    missing = [n for n in names if n not in docs]
    extra = [n for n in docs if n not in names]
    if missing or extra:
        raise TypeError(f"TOML table of {cls.__name__}: fields without an entry {missing}, "
                        f"entries without a field {extra}")


def toml_keys(cls: type, docs: Docs, section: str | None = None) -> dict[str, Key]:
    """The TOML keys of ``cls`` (of its ``section`` when given), in field order.

    Parameters
    ----------
    cls : dataclass type
    docs : dict
        One entry per field of ``cls``: a :class:`KeyDoc`, a tuple of them (a field
        written as several keys) or ``None`` (not a TOML key).
    section : str, optional
        Only the keys whose ``KeyDoc.section`` is this.
    """
    check_table(cls, docs)
    out = {}
    for f in dataclasses.fields(cls):
        entry = docs[f.name]
        for doc in (entry if isinstance(entry, tuple) else (entry,)):
            if doc is None or (section is not None and doc.section != section):
                continue
            default = field_default(f) if doc.default is FROM_FIELD else doc.default
            name = doc.key or f.name
            out[name] = Key(name, f.name, doc, default)
    return out


def key_names(docs: Docs, section: str) -> frozenset[str]:
    """The TOML names of the keys of ``section`` in a table whose entries name sections."""
    names = set()
    for field_name, entry in docs.items():
        for doc in (entry if isinstance(entry, tuple) else (entry,)):
            if doc is not None and doc.section == section:
                names.add(doc.key or field_name)
    return frozenset(names)
