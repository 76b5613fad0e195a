"""The README: short, and every command in it runs.

- at most :data:`MAX_CHARS` characters (what a newcomer needs first; the rest
  is in docs/);
- every fenced ``bash`` line is either a set-up command that ``.ci/run`` runs
  word for word, stopping on a failure (the install, test and docs-build
  lines: checked by their exact text, not run inside pytest), or an
  ``skfem-granular`` command, run
  here in order in a scratch directory and required to exit 0;
- every fenced ``python`` block runs (in that directory);
- every relative link points to a file of the checkout;
- the getting-started page quotes the README's test run time, not its own.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
CI = ROOT / ".ci" / "run"
MAX_CHARS = 8000
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.MULTILINE | re.DOTALL)


def blocks(lang: str) -> list[str]:
    return [body for kind, body in FENCE.findall(README.read_text()) if kind == lang]


def bash_lines() -> list[str]:
    out = []
    for body in blocks("bash"):
        for line in body.splitlines():
            words = shlex.split(line, comments=True)
            if words:
                out.append(line.split(" #")[0].rstrip() if " #" in line else line.rstrip())
    return out


def _setup_line(line: str) -> bool:
    return line.startswith(("python3 -m venv ", ".venv/bin/pip install "))


def test_readme_is_short():
    assert len(README.read_text()) <= MAX_CHARS


def test_readme_set_up_commands_are_what_ci_runs():
    ci = CI.read_text().splitlines()
    setup = [line for line in bash_lines() if _setup_line(line)]
    assert len(setup) >= 3  # install and run, test, build the docs
    for line in setup:  # word for word, a failure ending the run
        assert f"{line} || exit $?" in ci, f".ci/run does not run the README's {line!r}"


def test_readme_commands_are_all_known():
    """No command in the README escapes the two tests below."""
    other = [line for line in bash_lines()
             if not _setup_line(line) and not line.startswith("skfem-granular ")]
    assert other == []


@pytest.fixture
def scratch(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_readme_cli_commands_run(scratch, capsys):
    from skfem_granular.cli import main

    cmds = [line for line in bash_lines() if line.startswith("skfem-granular ")]
    assert len(cmds) >= 4
    for line in cmds:
        code = main(shlex.split(line, comments=True)[1:])
        out = capsys.readouterr()
        assert code == 0, (line, out.err[-2000:])
    assert (scratch / "out" / "sp" / "speed.png").stat().st_size > 0
    assert (scratch / "out" / "sp" / "history.csv").read_text().count("\n") == 41  # 40 steps


def test_readme_python_blocks_run(scratch, capsys):
    code = blocks("python")
    assert code, "the README has no library example"
    for i, body in enumerate(code):
        exec(compile(body, f"README.md python block {i}", "exec"), {"__name__": "readme"})
    out = capsys.readouterr().out
    assert "v_y = " in out and "F_y = " in out  # the generator loop printed steps
    assert (scratch / "out" / "sp_python" / "summary.json").exists()


def test_readme_links_exist():
    text = README.read_text()
    links = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", text)
    local = [link for link in links if "://" not in link]
    assert local
    missing = [link for link in local if not (ROOT / link).exists()]
    assert missing == []


def test_getting_started_quotes_the_readme_test_time():
    """The default test run's time is measured once, in the README; the getting-started
    page says the same."""
    pattern = re.compile(r"about (\d+) min on 2 cores")
    readme = pattern.findall(README.read_text())
    page = pattern.findall((ROOT / "docs" / "getting_started.md").read_text())
    assert len(readme) == 1 and page == readme
