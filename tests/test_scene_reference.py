"""The scene-file reference (docs/scene_reference.md) against the parser and the dataclasses.

- the committed page is what :func:`scene_reference` writes today, byte for byte;
- every key of every bundled scene is in it, under its section;
- the parser accepts every key it lists (no "unknown key"), and refuses any
  other with one line whose list of allowed keys is exactly the page's;
- every field of the dataclasses the parser fills is listed (or is one the
  TOML layout does not write), and the defaults on the page are the fields'
  defaults, and the values a scene gets when it leaves the key out.
"""

import dataclasses
import inspect
import re
import tomllib
from pathlib import Path

import pytest

from skfem_granular.dem import ContactLaw, Polygon, PrescribedMotion
from skfem_granular.fluid import Fluid
from skfem_granular.scene import (
    Effects,
    GridSpec,
    MeshSpec,
    ParticleSpec,
    Scene,
    TimeSpec,
    bundled_scenes,
)
from skfem_granular.scene.column import ColumnSpec
from skfem_granular.scene.reference import main, scene_reference

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "scene_reference.md"


def _section_name(heading: str) -> str:
    """``[time]`` -> ``time``, ``[[particles]]`` -> ``particles``, the motion's -> dotted."""
    heading = heading.replace("`", "").strip()
    if heading == "Top level":
        return ""
    if heading.startswith("motion ="):
        return "particles.motion"
    return heading.strip("[]")


def _rows(text: str) -> dict[str, dict[str, dict[str, str]]]:
    """``{section: {key: {column: cell}}}`` of the page's tables."""
    out: dict[str, dict[str, dict[str, str]]] = {}
    section, columns = None, None
    for line in text.splitlines():
        if line.startswith("## "):
            section, columns = _section_name(line[3:]), None
            out[section] = {}
        elif line.startswith("|") and section is not None:
            cells = [c.strip().replace("\\|", "|")
                     for c in re.split(r"(?<!\\)\|", line.strip())[1:-1]]
            if columns is None:
                columns = cells
            elif not set(cells[0]) <= {"-", " "}:
                row = dict(zip(columns, cells, strict=True))
                out[section][row["key"].strip("`")] = row
    return out


ROWS = _rows(PAGE.read_text(encoding="utf-8"))


def test_page_is_generated_from_the_dataclasses():
    assert PAGE.read_text(encoding="utf-8") == scene_reference(), (
        "docs/scene_reference.md is out of date: python -m skfem_granular.scene.reference "
        "docs/scene_reference.md")


def test_main_writes_the_page(tmp_path):
    out = tmp_path / "ref.md"
    assert main([str(out)]) == 0
    assert out.read_bytes() == PAGE.read_bytes()


def test_every_section_has_a_table_with_every_column():
    expected = {"", "domain", "fluid", "particles", "particles.motion", "grid", "column",
                "contacts", "mesh", "time", "effects", "coupling", "output"}
    assert set(ROWS) == expected
    for section, rows in ROWS.items():
        assert rows, section
        for key, row in rows.items():
            assert list(row) == ["key", "type", "unit", "default", "allowed", "meaning"]
            assert row["type"] and row["default"] and row["allowed"] and row["meaning"], key


def _keys_used(data: dict) -> set[tuple[str, str]]:
    """``(section, key)`` of every key a scene file writes."""
    used = set()
    for top, value in data.items():
        if top == "particles":
            for p in value:
                used |= {("particles", k) for k in p}
                used |= {("particles.motion", k) for k in p.get("motion", {})}
        elif isinstance(value, dict):
            used |= {(top, k) for k in value}
        else:
            used.add(("", top))
    return used


def test_every_key_of_every_bundled_scene_is_in_the_reference():
    scenes = bundled_scenes()
    assert len(scenes) >= 13
    used = set()
    for path in scenes.values():
        used |= _keys_used(tomllib.loads(path.read_text(encoding="utf-8")))
    missing = sorted(f"{s}.{k}" for s, k in used if k not in ROWS.get(s, {}))
    assert missing == []
    # the walk found the sections the bundled scenes write
    assert {s for s, _ in used} >= {"domain", "fluid", "particles", "grid", "contacts", "mesh",
                                    "time", "effects", "coupling", "output"}


# a valid scene (the paper's single particle, two steps) to add one key at a time to
BASE = {
    "domain": {"box": [0.0, 0.0, 3e-3, 11e-3]},
    "fluid": {"density": 1000.0, "viscosity": 1e-3},
    "particles": [{"sides": 24, "radius": 0.5e-3, "center": [1.5e-3, 5.5e-3],
                   "density": 2650.0}],
    "time": {"t_end": 2e-5, "dt": 1e-5},
}
GRID = {"nx": 1, "ny": 1, "radius": 0.2e-3, "origin": [1.5e-3, 1e-3]}


def _with(section: str, key: str, value) -> dict:
    """:data:`BASE` with ``section.key = value`` (the section added when missing)."""
    data = {k: (v if k != "particles" else [dict(p) for p in v]) for k, v in BASE.items()}
    if section == "":
        data[key] = value
    elif section == "particles":
        data["particles"][0][key] = value
    elif section == "particles.motion":
        data["particles"][0]["motion"] = {key: value}
    else:
        data[section] = {**data.get(section, GRID if section == "grid" else {}), key: value}
    return data


def _value(row: dict[str, str]):
    """The key's default from the page, or a string where there is none (a bad value)."""
    cell = row["default"].strip("`")
    if cell in ("*required*", "*none*"):
        return "x"
    return tomllib.loads(f"v = {cell}")["v"]


@pytest.mark.parametrize("section", sorted(ROWS))
def test_the_parser_accepts_every_listed_key(section):
    for key, row in ROWS[section].items():
        try:
            Scene.from_dict(_with(section, key, _value(row)))
        except ValueError as exc:
            assert "unknown key" not in str(exc), f"{section}.{key}: {exc}"


@pytest.mark.parametrize("section", sorted(ROWS))
def test_an_unknown_key_fails_with_one_line_naming_the_listed_keys(section):
    with pytest.raises(ValueError) as info:
        Scene.from_dict(_with(section, "not_a_key", 1.0))
    where = {"": "scene", "particles": "particles[0]",
             "particles.motion": "particles[0].motion"}.get(section, section)
    allowed = sorted(ROWS[section])
    if section == "":  # the top level also names the sections
        allowed = sorted(set(allowed) | {s.split(".")[0] for s in ROWS if s})
    msg = str(info.value)
    assert "\n" not in msg
    assert msg == f"{where}: unknown key 'not_a_key'; allowed keys are {', '.join(allowed)}"


#: The dataclass each section fills, and the fields not written in TOML (with why).
CLASSES = {
    "fluid": (Fluid, set()),
    "particles": (ParticleSpec, {"polygon"}),  # as vertices, or sides/radius/center/angle
    "particles.motion": (PrescribedMotion, set()),
    "grid": (GridSpec, set()),
    "column": (ColumnSpec, set()),
    "contacts": (ContactLaw, {"gamma_t", "kt_ratio", "damping_cap"}),  # library only
    "mesh": (MeshSpec, set()),
    "time": (TimeSpec, set()),
    "effects": (Effects, set()),
}
#: The Scene's fields written in its own sections, as (section, TOML name).
SCENE_FIELDS = {"domain": ("domain", "box"), "wall_thickness": ("domain", "wall_thickness"),
                "gravity": ("", "gravity"), "coupling": ("coupling", "scheme"),
                "remesh_fraction": ("coupling", "remesh_fraction"),
                "mesh_motion": ("coupling", "mesh_motion"),
                "remesh_travel": ("coupling", "remesh_travel"),
                "mesh_repair": ("coupling", "mesh_repair"),
                "newton_tol": ("coupling", "newton_tol"),
                "output_dir": ("output", "directory"), "vtu_every": ("output", "vtu_every"),
                "checkpoint_every": ("output", "checkpoint_every")}
#: Scene fields that are whole sections, or not in the file at all.
SCENE_ELSEWHERE = {"particles", "fluid", "contact_law", "mesh", "time", "effects",
                   "name",  # the file's stem
                   "overlap_tolerance"}  # set by a [column]'s packing


def _default(f: dataclasses.Field):
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return dataclasses.MISSING


def _page_default(row: dict[str, str]):
    cell = row["default"]
    if cell == "*required*":
        return dataclasses.MISSING
    if cell == "*none*":
        return None
    value = tomllib.loads(f"v = {cell.strip('`')}")["v"]
    return tuple(value) if isinstance(value, list) else value


def test_every_field_is_listed_with_its_default():
    checked = 0
    for section, (cls, left_out) in CLASSES.items():
        for f in dataclasses.fields(cls):
            if f.name in left_out:
                assert f.name not in ROWS[section]
                continue
            assert _page_default(ROWS[section][f.name]) == _default(f), f"{section}.{f.name}"
            checked += 1
    for f in dataclasses.fields(Scene):
        if f.name in SCENE_ELSEWHERE:
            continue
        section, key = SCENE_FIELDS[f.name]
        assert _page_default(ROWS[section][key]) == _default(f), f"{section}.{key}"
        checked += 1
    assert checked == sum(len(rows) for rows in ROWS.values()) - 5  # 5 polygon keys
    angle = inspect.signature(Polygon.regular).parameters["angle"].default
    assert _page_default(ROWS["particles"]["angle"]) == angle
    for key in ("vertices", "sides", "radius", "center"):
        assert ROWS["particles"][key]["default"] == "*required*"


def test_a_scene_leaving_a_key_out_gets_the_listed_default():
    """What the parser fills in, read back from built scenes (not from the dataclasses)."""
    data = {**BASE, "grid": GRID, "fluid": {}, "contacts": {}, "mesh": {},
            "time": {"t_end": 1e-3}, "effects": {}, "coupling": {}, "output": {}}
    scene = Scene.from_dict(data)
    got = {
        "fluid": scene.fluid, "contacts": scene.contact_law, "mesh": scene.mesh,
        "time": scene.time, "effects": scene.effects,
        "particles": scene.particles[0], "grid": scene.particles[1],
    }
    for section in ("fluid", "contacts", "mesh", "time", "effects"):
        for key, row in ROWS[section].items():
            if section == "time" and key == "t_end":
                continue
            assert getattr(got[section], key) == _page_default(row), f"{section}.{key}"
    for key in ("velocity", "angular_velocity", "core_ratio", "motion"):
        for which in ("particles", "grid"):
            if which == "grid" and key not in ROWS["grid"]:
                continue
            assert getattr(got[which], key) == _page_default(ROWS[which][key]), key
    grid = scene.particles[1]
    assert grid.density == _page_default(ROWS["grid"]["density"])
    assert grid.polygon.vertices.shape[1] == _page_default(ROWS["grid"]["sides"])
    for f, (section, key) in SCENE_FIELDS.items():
        if ROWS[section][key]["default"] != "*required*":
            assert getattr(scene, f) == _page_default(ROWS[section][key]), f"{section}.{key}"


def test_a_field_without_a_table_entry_is_refused():
    """Adding a field to a section's dataclass without saying how TOML writes it fails."""
    from skfem_granular.scene._keys import KeyDoc, check_table, toml_keys
    from skfem_granular.scene.sections import TIME_DOCS

    @dataclasses.dataclass(frozen=True)
    class Longer(TimeSpec):
        substeps: int = 1

    with pytest.raises(TypeError, match=r"Longer: fields without an entry \['substeps'\]"):
        toml_keys(Longer, TIME_DOCS)
    with pytest.raises(TypeError, match=r"entries without a field \['gone'\]"):
        check_table(TimeSpec, {**TIME_DOCS, "gone": KeyDoc("float", "a removed field")})
    keys = toml_keys(Longer, {**TIME_DOCS, "substeps": KeyDoc("integer", "sub-steps")})
    assert list(keys)[-1] == "substeps" and keys["substeps"].default == 1


_NUMBER = r"-?\d[\d.e+-]*"


def _bad_values(row: dict[str, str]) -> list[tuple[object, str]]:
    """``(value, bound)``: a value just outside each numeric bound of the allowed column
    (``> 0``, ``>= -1000``, ``<= 1.6``, ``in [3, 1000]``) and that bound's text."""
    integer = row["type"] == "`integer`"
    out: list[tuple[object, str]] = []
    for piece in re.split(r" and |; ", row["allowed"]):
        piece = piece.strip()
        if m := re.fullmatch(rf"(>=|>|<=) ({_NUMBER})", piece):
            op, x = m.group(1), float(m.group(2))
            bad = {">": x, ">=": x - 1 if integer else x - 0.5 * max(abs(x), 0.1),
                   "<=": x + 1 if integer else 2 * x if x > 0 else x + 1}[op]
            out.append((int(bad) if integer else bad, piece))
        elif m := re.fullmatch(rf"in \[({_NUMBER}), ({_NUMBER})\]", piece):
            lo, hi = float(m.group(1)), float(m.group(2))
            if integer:
                out += [(int(lo) - 1, piece), (int(hi) + 1, piece)]
            else:
                out += [(lo / 10 if lo > 0 else lo - 1, piece), (hi * 10, piece)]
    return out


def test_the_allowed_ranges_are_the_ones_the_checks_name():
    """A value just outside a listed bound fails with one line naming the key and that bound."""
    where = {"": "scene", "particles": "particles[0]"}
    checked = 0
    for section, rows in ROWS.items():
        for key, row in rows.items():
            for bad, bound in _bad_values(row):
                with pytest.raises(ValueError) as info:
                    if section == "column":  # its ranges apply once the packing is read
                        ColumnSpec("packing.npz", **{key: bad})
                    else:
                        Scene.from_dict(_with(section, key, bad))
                msg = str(info.value)
                name = f"{where.get(section, section)}.{key} = "
                assert "\n" not in msg and msg.startswith(name) and bound in msg, (bad, msg)
                checked += 1
    assert checked >= 40
