"""Scenes shipped with the package (``library/*.toml``), found by name.

``bundled("single-particle")``, ``bundled("single_particle")`` and
``bundled("single_particle.toml")`` all give the path of
``library/single_particle.toml`` inside the installed package; the files are
package data, read through :mod:`importlib.resources`.
"""

from __future__ import annotations

import atexit
from contextlib import ExitStack
from importlib import resources
from pathlib import Path

_SUFFIX = ".toml"
_extracted = ExitStack()  # files of a zipped install, extracted for the run's lifetime
atexit.register(_extracted.close)


def _as_path(entry) -> Path:
    """A real file path for a package resource (extracted when the package is zipped)."""
    if isinstance(entry, Path):
        return entry
    return _extracted.enter_context(resources.as_file(entry))


def bundled_scenes() -> dict[str, Path]:
    """The bundled scenes, ``{name: path}`` sorted by name (names are the file stems)."""
    lib = resources.files(__package__).joinpath("library")
    entries = sorted(
        (e for e in lib.iterdir() if e.is_file() and e.name.endswith(_SUFFIX)),
        key=lambda e: e.name,
    )
    return {e.name[: -len(_SUFFIX)]: _as_path(e) for e in entries}


def bundled(name: str) -> Path:
    """The path of the bundled scene ``name`` (``.toml`` optional; ``-`` and ``_`` alike)."""
    scenes = bundled_scenes()
    key = name.strip().removesuffix(_SUFFIX).replace("-", "_") if isinstance(name, str) else None
    if key not in scenes:
        raise ValueError(
            f"scene {name!r}: no bundled scene of that name; bundled scenes are "
            f"{', '.join(scenes)}"
        )
    return scenes[key]


def first_comment(path) -> str:
    """The first ``#`` comment line of a scene file, without the ``#`` ('' if none)."""
    for line in Path(path).read_text(encoding="utf-8").splitlines():
        if line.lstrip().startswith("#"):
            return line.lstrip().lstrip("#").strip()
    return ""
