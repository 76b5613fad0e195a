"""One benchmark run in a fresh interpreter: its own CPU time and peak memory.

A script that measures runs one at a time calls itself with ``--child ARGS``; the child
prints its record as the last line of its output, one JSON object.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run_child(script: str, *args) -> dict:
    """``python script --child ARGS`` with the repository and ``benchmarks/`` importable;
    the record the child printed last."""
    cmd = [sys.executable, str(Path(script).resolve()), "--child", *map(str, args)]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        p for p in (str(ROOT), str(ROOT / "benchmarks"), os.environ.get("PYTHONPATH")) if p)}
    out = subprocess.run(cmd, check=True, stdout=subprocess.PIPE, text=True, env=env)
    return json.loads(out.stdout.strip().splitlines()[-1])
