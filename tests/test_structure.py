"""The package's import rules, read from the source with ``ast`` (nothing is imported).

- no import circle among the modules of ``skfem_granular`` nor among those of
  ``meshing`` (package ``__init__`` files, which only re-export, left out), counting
  function-local imports too;
- no module imports a private name (``_x``) from another module, except from a
  designated private helper module (one whose own name starts with ``_``);
- nothing outside the coupled stepper and the simulation reaches into a private attribute of a
  simulation or a stepper (``sim._x``, ``stepper._x``);
- ``meshing`` never imports ``skfem_granular``; the DEM never imports ``skfem`` or
  ``meshing``.
"""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "skfem_granular"


def _modules(root: Path, package: str) -> dict[str, Path]:
    out = {}
    for f in root.rglob("*.py"):
        parts = (package,) + f.relative_to(root).with_suffix("").parts
        name = ".".join(parts)
        out[name.removesuffix(".__init__")] = f
    return out


MODULES = _modules(PKG, "skfem_granular")
MESHING = _modules(ROOT / "meshing", "meshing")


def _imports(name: str, path: Path):
    """``(target module, imported name)`` of every ``from ... import`` in a module."""
    tree = ast.parse(path.read_text())
    is_pkg = path.name == "__init__.py"
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".")
                if not is_pkg:
                    base = base[:-1]
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            for alias in node.names:
                yield target, alias.name
        elif isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, None


def _edges(modules: dict[str, Path]) -> dict[str, set[str]]:
    edges: dict[str, set[str]] = {}
    for name, path in modules.items():
        for target, item in _imports(name, path):
            full = f"{target}.{item}" if item else target
            mod = full if full in modules else target
            if mod in modules and mod != name:
                edges.setdefault(name, set()).add(mod)
    return edges


def import_circles(modules: dict[str, Path]) -> list[str]:
    """The modules (package faces left out) that reach themselves by imports."""
    faces = {m for m, f in modules.items() if f.name == "__init__.py"}
    graph = {m: {t for t in ts if t not in faces}
             for m, ts in _edges(modules).items() if m not in faces}

    def reaches(start, goal, seen):
        for nxt in graph.get(start, ()):
            if nxt == goal:
                return True
            if nxt not in seen:
                seen.add(nxt)
                if reaches(nxt, goal, seen):
                    return True
        return False

    return sorted(m for m in graph if reaches(m, m, set()))


@pytest.mark.parametrize("package", ["skfem_granular", "meshing"])
def test_no_import_circle(package):
    circles = import_circles(MODULES if package == "skfem_granular" else MESHING)
    assert circles == [], f"modules on an import circle: {circles}"


def test_no_private_name_imported_across_modules():
    bad = []
    for name, path in MODULES.items():
        for target, item in _imports(name, path):
            if item is None or not item.startswith("_") or item.startswith("__"):
                continue
            full = f"{target}.{item}"
            source = full if full in MODULES else target
            if not source.startswith("skfem_granular"):
                continue
            if source.rsplit(".", 1)[-1].startswith("_"):
                continue  # a designated private helper module
            bad.append(f"{name} <- {target}.{item}")
    assert bad == [], f"private names imported across modules: {bad}"


def test_nothing_reaches_into_a_simulation_or_stepper():
    owners = {"sim", "simulation", "stepper"}
    bad = []
    for name, path in MODULES.items():
        if name in ("skfem_granular.coupled.stepper", "skfem_granular.simulation.run"):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if (isinstance(node, ast.Attribute) and node.attr.startswith("_")
                    and not node.attr.startswith("__")):
                base = node.value
                if isinstance(base, ast.Attribute) and base.attr in owners:
                    bad.append(f"{name}:{node.lineno} .{base.attr}.{node.attr}")
                elif isinstance(base, ast.Name) and base.id in owners:
                    bad.append(f"{name}:{node.lineno} {base.id}.{node.attr}")
    assert bad == [], f"private attributes of a simulation or stepper used outside: {bad}"


def test_meshing_and_dem_stay_independent():
    bad = [f"{n} imports {t}" for n, p in MESHING.items() for t, _ in _imports(n, p)
           if t.split(".")[0] == "skfem_granular"]
    dem = {n: p for n, p in MODULES.items() if n.startswith("skfem_granular.dem")}
    bad += [f"{n} imports {t}" for n, p in dem.items() for t, _ in _imports(n, p)
            if t.split(".")[0] in ("skfem", "meshing")]
    assert bad == []


def test_the_rules_catch_what_they_are_for(tmp_path):
    """The checks find a circle and a private import in a small made-up package, and a
    circle closed by a function-local import in a made-up ``meshing``, but not the
    package faces' re-exports."""
    global MODULES
    pkg = tmp_path / "skfem_granular"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("from .a import f\nfrom .b import g\n")
    (pkg / "a.py").write_text("from .b import f\n")
    (pkg / "b.py").write_text("def f():\n    from .a import _g\n")
    (pkg / "c.py").write_text("from . import a\n")
    mesher = tmp_path / "meshing"
    mesher.mkdir()
    (mesher / "__init__.py").write_text("from .graded import graded_mesh\n"
                                        "from .value import build\n")
    (mesher / "value.py").write_text("def build():\n    from .graded import build_graded\n")
    (mesher / "graded.py").write_text("from .value import build\n")
    (mesher / "plot.py").write_text("import meshing.value\n")
    assert import_circles(_modules(pkg, "skfem_granular")) == ["skfem_granular.a",
                                                               "skfem_granular.b"]
    assert import_circles(_modules(mesher, "meshing")) == ["meshing.graded", "meshing.value"]
    saved, MODULES = MODULES, _modules(pkg, "skfem_granular")
    try:
        try:
            test_no_private_name_imported_across_modules()
        except AssertionError:
            pass
        else:
            raise AssertionError("the private-name check missed the planted finding")
    finally:
        MODULES = saved


#: Longest function, in lines (its docstring not counted).
MAX_FUNCTION_LINES = 80


def code_lines(fn: ast.FunctionDef | ast.AsyncFunctionDef, lines: list[str]) -> int:
    """Lines of a function from its first statement after the docstring to its end
    (blank lines and comments inside count, nested functions in full)."""
    body = fn.body
    doc = (isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant)
           and isinstance(body[0].value.value, str))
    if doc and len(body) == 1:
        return 0
    first = body[1].lineno if doc else body[0].lineno
    return len(lines[first - 1:fn.end_lineno])


def long_functions(paths, base: Path = ROOT) -> list[str]:
    out = []
    for path in paths:
        text = path.read_text()
        lines = text.splitlines()
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                n = code_lines(node, lines)
                if n > MAX_FUNCTION_LINES:
                    out.append(f"{path.relative_to(base)}:{node.lineno} {node.name}: {n} lines")
    return out


def test_no_function_longer_than_80_lines():
    paths = [p for pkg in ("skfem_granular", "meshing") for p in sorted((ROOT / pkg).rglob("*.py"))]
    assert len(paths) > 100
    assert long_functions(paths) == []


def test_function_length_leaves_out_the_docstring(tmp_path):
    body = "\n".join(f"    x{k} = {k}" for k in range(78))  # + y, a comment, a blank: 81
    src = (f'def long():\n    """Doc.\n\n    more doc\n    """\n    y = 0\n    # a comment\n\n'
           f'{body}\n\n'
           f'def short():\n    """Doc.\n' + "\n".join(f"    line {k}" for k in range(90))
           + '\n    """\n    return 1\n')
    p = tmp_path / "probe.py"
    p.write_text(src)
    assert long_functions([p], base=tmp_path) == ["probe.py:1 long: 81 lines"]


def test_docs_and_code_speak_of_the_library_not_its_issues():
    """No issue numbers in page titles, prose, docstrings, benchmark scripts, the bundled
    scenes' comments (``skfem-granular scenes`` prints their first lines) or the package's
    data files."""
    import re

    pattern = re.compile(r"\b[Ii]ssue\s+#?\d+|\(issue\b|\b(the|this|that) issue\b", re.I)
    paths = ([p for pkg in ("skfem_granular", "meshing", "benchmarks") for p in
              sorted((ROOT / pkg).rglob("*.py"))] + sorted((ROOT / "docs").glob("*.md"))
             + [ROOT / "README.md"]
             + [p for ext in ("*.toml", "*.json") for p in sorted(PKG.rglob(ext))])
    found = [f"{p.relative_to(ROOT)}:{k + 1}" for p in paths
             for k, line in enumerate(p.read_text().splitlines()) if pattern.search(line)]
    assert found == []
