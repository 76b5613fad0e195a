"""The package installed as a user gets it: a wheel in a fresh environment, run elsewhere.

``pip install <checkout>`` (not editable: setuptools builds a wheel) into a
new virtual environment outside the checkout, then, from another directory:
the bundled scenes are listed (package data), the main job writes the usual
outputs, a checkpoint resumes, and the smoke Faxen study writes its table
(the study's figures need matplotlib, installed next to the package). The
installed package must be the one imported, not the checkout's.

Slow (downloads or reuses pip's cache: about 1-3 min); ``.ci/run`` runs it.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(cmd, cwd, timeout=1800):
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "VIRTUAL_ENV", "NUMBA_CACHE_DIR")}
    p = subprocess.run([str(c) for c in cmd], cwd=cwd, env=env, capture_output=True, text=True,
                       timeout=timeout)
    assert p.returncode == 0, f"{cmd}: exit {p.returncode}\n{p.stdout[-3000:]}\n{p.stderr[-3000:]}"
    return p.stdout


@pytest.mark.slow
def test_wheel_installs_and_runs_outside_the_checkout(tmp_path):
    venv = tmp_path / "venv"
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    _run([sys.executable, "-m", "venv", venv], tmp_path)
    py, exe = venv / "bin" / "python", venv / "bin" / "skfem-granular"
    _run([py, "-m", "pip", "install", "--quiet", ROOT, "matplotlib"], elsewhere)
    where = _run([py, "-c", "import skfem_granular, meshing; print(skfem_granular.__file__); "
                            "print(meshing.__file__)"], elsewhere).split()
    assert all(str(venv) in w and str(ROOT) not in w for w in where), where
    # the PEP 561 markers: type checkers use the packages' annotations
    assert all((Path(w).parent / "py.typed").is_file() for w in where), where
    scenes = _run([exe, "scenes"], elsewhere)
    assert "single_particle" in scenes and "collapse" in scenes
    out = tmp_path / "x"
    _run([exe, "run", "single-particle", "--out", out, "--checkpoint-every", "50",
          "--no-progress"], elsewhere)
    for name in ("flow.pvd", "particles.pvd", "history.csv", "summary.json", "checkpoint.npz",
                 "flow_00000.vtu", "flow_00010.vtu", "particles_00010.vtu"):
        assert (out / name).stat().st_size > 0, name
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "completed" and s["steps"] == 100
    assert (out / "history.csv").read_text().count("\n") == 101
    # numba's disk cache of the kernels the run compiled, next to the installed sources
    assert list(Path(where[0]).parent.rglob("__pycache__/*.nbi")), "no numba cache written"
    _run([exe, "run", "--resume", out, "--t-end", "1.1e-3", "--no-progress"], elsewhere)
    assert (out / "history.csv").read_text().count("\n") == 111
    study = tmp_path / "faxen"
    text = _run([exe, "study", "faxen", "--smoke", "--out", study], elsewhere)
    assert "runs computed" in text and "0 failed" in text
    assert (study / "table.csv").stat().st_size > 0 and (study / "pareto.png").exists()
