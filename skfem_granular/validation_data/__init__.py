"""Published reference values for the validation checks, as package data.

Each ``<name>.json`` here holds the literature numbers of one family of
checks together with their sources (authors, journal, volume, year, table or
figure, and where the value was found), and says ``"status": "not found"``
where no published value could be found and checked. ``load(name)`` reads one
file through :mod:`importlib.resources` (so it works from a wheel or a zip).

>>> from skfem_granular.validation_data import load
>>> data = load("sedimentation")
>>> data["sources"]["glowinski2001"]["journal"]
'Journal of Computational Physics'
"""

from __future__ import annotations

import json
from importlib import resources

__all__ = ["available", "load"]


def available() -> list[str]:
    """Names of the data files (``load`` accepts each)."""
    return sorted(e.name[:-5] for e in resources.files(__package__).iterdir()
                  if e.name.endswith(".json"))


def load(name: str) -> dict:
    """The reference data ``name`` (``"sedimentation"``; ``.json`` optional)."""
    key = name.removesuffix(".json") if isinstance(name, str) else None
    names = available()
    if key not in names:
        raise ValueError(f"validation data {name!r}: no such file; available: {', '.join(names)}")
    text = resources.files(__package__).joinpath(f"{key}.json").read_text(encoding="utf-8")
    return json.loads(text)
