"""No pickle in the package: its files are plain data (JSON, CSV, VTU, npz of plain arrays).

Read from the source (nothing is imported): no module imports ``pickle`` or a
relative of it (``dill``, ``cloudpickle``, ``joblib``, ``shelve``, ``marshal``),
every ``numpy.load`` passes ``allow_pickle=False``, and the word appears
nowhere else but in ``allow_pickle=False`` and in comments, docstrings and
messages that say it is *not* used (a line with "not", "no", "never",
"nothing", "without" or "refused").
"""

import ast
import io
import re
import tokenize
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = (ROOT / "skfem_granular", ROOT / "meshing")
FORBIDDEN_MODULES = {"pickle", "cPickle", "_pickle", "dill", "cloudpickle", "joblib", "shelve",
                     "marshal", "copyreg"}
NEGATION = re.compile(r"\b(not|no|never|nothing|without|refused?|refuses)\b|allow_pickle=False",
                      re.IGNORECASE)
TEXT_TOKENS = {tokenize.COMMENT, tokenize.STRING} | (
    {tokenize.FSTRING_MIDDLE} if hasattr(tokenize, "FSTRING_MIDDLE") else set())


def _sources(roots=PACKAGES):
    return sorted(f for r in roots for f in r.rglob("*.py"))


def findings(path: Path) -> list[str]:
    text = path.read_text()
    bad = []
    toks = list(tokenize.generate_tokens(io.StringIO(text).readline))
    for i, tok in enumerate(toks):
        if "pickle" not in tok.string.lower():
            continue
        where = f"{path.relative_to(path.parents[1])}:{tok.start[0]}"
        if (tok.type == tokenize.NAME and tok.string == "allow_pickle"
                and [t.string for t in toks[i + 1:i + 3]] == ["=", "False"]):
            continue
        if tok.type in TEXT_TOKENS:
            for line in tok.string.splitlines():
                if "pickle" in line.lower() and not NEGATION.search(line):
                    bad.append(f"{where}: {line.strip()!r} mentions pickle without saying "
                               "it is not used")
            continue
        bad.append(f"{where}: {tok.string!r}")
    for node in ast.walk(ast.parse(text)):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            names = [node.module]
        for n in names:
            if n.split(".")[0] in FORBIDDEN_MODULES:
                bad.append(f"{path.name}:{node.lineno}: imports {n}")
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                and node.func.attr == "load" and isinstance(node.func.value, ast.Name)
                and node.func.value.id in ("np", "numpy")):
            kw = {k.arg: k.value for k in node.keywords}
            v = kw.get("allow_pickle")
            if not (isinstance(v, ast.Constant) and v.value is False):
                bad.append(f"{path.name}:{node.lineno}: numpy.load without allow_pickle=False")
    return bad


def test_no_pickle_in_the_package():
    bad = [b for f in _sources() for b in findings(f)]
    assert bad == []


def test_the_check_finds_what_it_is_for(tmp_path):
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "a.py").write_text(
        "import pickle  # fast\n"
        "import numpy as np\n"
        "x = np.load('f.npz')\n"
        "y = np.load('f.npz', allow_pickle=False)\n"
        "def f():\n"
        "    '''Pickles the state.'''\n"
        "    # not pickled: plain data\n")
    bad = findings(pkg / "a.py")
    assert any("'pickle'" in b for b in bad)              # the import statement's name
    assert any("imports pickle" in b for b in bad)
    assert any("without allow_pickle=False" in b for b in bad)
    assert any("Pickles the state" in b for b in bad)       # a docstring that uses it
    assert not any("not pickled" in b for b in bad)         # a comment that says it is not
    assert sum("numpy.load" in b for b in bad) == 1
