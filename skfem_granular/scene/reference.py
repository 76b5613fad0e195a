"""The scene-file reference: every section and key, made from the dataclasses (Markdown).

:func:`scene_reference` writes one table per section of :data:`.layout.LAYOUT`
(key, type, unit, default, allowed values, meaning); the keys and their
defaults come from the fields of the dataclasses the parser fills, so the page
lists exactly what :mod:`.parse` accepts. The documentation's
``docs/scene_reference.md`` is its output (a test regenerates it and compares);
rewrite it with ``python -m skfem_granular.scene.reference docs/scene_reference.md``.
"""

from __future__ import annotations

import sys
from pathlib import Path

from ._keys import REQUIRED, Key, toml_keys
from .layout import LAYOUT, Section
from .scene import Scene

__all__ = ["main", "scene_reference", "section_keys", "toml_value"]

_INTRO = """\
# Scene-file reference

Every key of a scene file, section by section: its TOML type, unit, default,
allowed values and meaning. A scene file is TOML (the [user guide](user_guide.md)
shows one whole); each section fills one dataclass of `skfem_granular.scene`
(named under its heading), and its keys are that dataclass's fields, so this
page is generated from them
(`python -m skfem_granular.scene.reference docs/scene_reference.md`; a test
checks it is up to date). A key not listed is refused, and so is a value
outside *allowed*, with one line naming the key and the allowed values
(`time.dt = -1.0: must be a finite number > 0`).

Default *required*: the scene must give the key; *none*: the key may be left
out, and the meaning says what happens then.
"""


def toml_value(value: object) -> str:
    """A default as TOML writes it (``true``, ``"auto"``, ``[0.0, -9.81]``), or
    ``required`` / ``none``."""
    if value is REQUIRED:
        return "required"
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, (int, float)):
        return repr(value)
    raise TypeError(f"no TOML form for a default of type {type(value).__name__}")


def section_keys(s: Section) -> dict[str, Key]:
    """The keys of a section with their defaults, from its dataclass's fields."""
    return toml_keys(Scene if s.cls is None else s.cls, s.docs,
                     section=s.name if s.cls is None else None)


def _cell(text: str) -> str:
    """Text for a Markdown table cell."""
    return text.replace("|", "\\|")


def _code(text: str) -> str:
    return f"`{text}`" if text else ""


def _table(s: Section) -> list[str]:
    rows = ["| key | type | unit | default | allowed | meaning |",
            "| --- | --- | --- | --- | --- | --- |"]
    for key in section_keys(s).values():
        d = key.doc
        default = toml_value(key.default)
        default = _code(default) if default not in ("required", "none") else f"*{default}*"
        rows.append("| " + " | ".join(_cell(c) for c in (
            _code(key.name), _code(d.type), d.unit, default, d.allowed, d.meaning)) + " |")
    return rows


def scene_reference() -> str:
    """The reference of every section and key of a scene file, as a Markdown page."""
    out = [_INTRO]
    for s in LAYOUT:
        cls = (Scene if s.cls is None else s.cls).__name__
        heading = _code(s.heading) if s.name else s.heading
        out += [f"## {heading}", "", f"{s.intro} Fills `{cls}`.", "", *_table(s), ""]
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    """Write the reference to the file named in ``argv`` (standard output without one)."""
    args = sys.argv[1:] if argv is None else argv
    text = scene_reference()
    if args:
        Path(args[0]).write_text(text, encoding="utf-8")
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
