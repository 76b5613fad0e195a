"""Start-up: what ``import skfem_granular`` loads, and numba's disk cache of the kernels.

- ``import skfem_granular`` loads none of the heavy optional or run-time-only
  modules (pyvista, matplotlib, pyamg, dask, numba, meshio, scipy.spatial): they
  are imported where they are used (a structural check in a fresh process, not
  a timing; ``benchmarks/startup.py`` times the process);
- the compiled kernels (:func:`skfem_granular._jit.lazy_njit`) go to numba's disk
  cache and a later process loads them from there, for a copy of the package
  outside the checkout (as installed);
- where no cache directory can be written (the package's ``__pycache__``,
  ``NUMBA_CACHE_DIR`` and the user's cache all unusable: a read-only
  installation) the kernels are compiled without the cache instead of failing.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

HEAVY = ("pyvista", "matplotlib", "pyamg", "dask", "numba", "meshio", "scipy.spatial")


def _python(code: str, env: dict | None = None, cwd=None) -> str:
    p = subprocess.run([sys.executable, "-c", code], env=env, cwd=cwd or ROOT,
                       capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, f"exit {p.returncode}\n{p.stdout[-3000:]}\n{p.stderr[-3000:]}"
    return p.stdout


def test_import_loads_no_heavy_module():
    out = _python("import json, sys, skfem_granular; "
                  f"print(json.dumps([m for m in {HEAVY!r} if m in sys.modules]))")
    loaded = json.loads(out.strip().splitlines()[-1])
    assert loaded == [], (f"import skfem_granular loads {loaded}: import them in the "
                          "functions that use them")


def _installed_copy(tmp_path: Path) -> Path:
    """The package copied outside the checkout (no ``__pycache__``), as pip installs it."""
    site = tmp_path / "site"
    shutil.copytree(ROOT / "skfem_granular", site / "skfem_granular",
                    ignore=shutil.ignore_patterns("__pycache__"))
    return site


# one triangle, and a second pose of it: mesh_quality's compiled kernel (a small one)
QUALITY = """
import json, numpy as np
from skfem_granular.coupled import mesh_motion
p = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
t = np.array([[0], [1], [2]])
angle, ratio = mesh_motion.mesh_quality(p, t, np.array([0.5]))
stats = mesh_motion._quality.stats
print(json.dumps({"file": mesh_motion.__file__, "angle": angle, "ratio": ratio,
                  "hits": sum(stats.cache_hits.values()),
                  "misses": sum(stats.cache_misses.values())}))
"""


def _quality(site: Path, **env) -> dict:
    env = dict(os.environ, PYTHONPATH=str(site), PYTHONDONTWRITEBYTECODE="1", **env)
    out = json.loads(_python(QUALITY, env=env, cwd=site).strip().splitlines()[-1])
    assert out["file"].startswith(str(site)), out["file"]  # the copy, not the checkout
    assert abs(out["angle"] - 45.0) < 1e-12 and abs(out["ratio"] - 1.0) < 1e-15
    return out


def test_kernels_are_cached_and_reused(tmp_path):
    site = _installed_copy(tmp_path)
    cache = tmp_path / "numba_cache"
    first = _quality(site, NUMBA_CACHE_DIR=str(cache))
    assert list(cache.rglob("mesh_motion._quality-*.nbi")), "no cache index written"
    second = _quality(site, NUMBA_CACHE_DIR=str(cache))
    assert first["hits"] == 0 and second["hits"] >= 1 and second["misses"] == 0


def test_kernels_compile_where_no_cache_can_be_written(tmp_path):
    site = _installed_copy(tmp_path)
    # a file where every cache directory would go: nothing can be created there
    for d in [site, *site.rglob("*")]:
        if d.is_dir():
            (d / "__pycache__").touch()
    blocked = tmp_path / "not_a_directory"
    blocked.touch()
    out = _quality(site, NUMBA_CACHE_DIR=str(blocked / "numba"), HOME=str(blocked),
                   XDG_CACHE_HOME=str(blocked / "cache"))
    assert out["hits"] == 0
    assert not any(p.name.endswith((".nbi", ".nbc")) for p in tmp_path.rglob("*"))
