"""Benchmark: the fill of SuperLU's threshold-pivoted fallback against its static factors.

Usage::

    python benchmarks/fallback_fill.py [--cases single_particle,n25,n100] [--tag NAME]

For each case, the largest matrix factorised in the first step of a run (the coupled
one; the paper's single particle, or the dense collapse column of ``n`` grains at core
ratio 0.9, monolithic coupling) is factorised twice in a fresh interpreter: as the
library does (static pivoting, the mesh's ordering) and as its fallback does when
refinement stalls (threshold pivoting 0.01, SuperLU's MMD_AT_PLUS_A ordering). Records
the unknowns, the factors' entries (``nnz``), their ratio, the time and the peak memory
of each (Linux ``VmHWM`` after resetting it). The ratio sets
:data:`skfem_granular.fluid.superlu.PIVOTED_FILL`, the margin the fallback's memory
guard assumes. Writes ``benchmarks/results/fallback_fill_<tag>.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from child_process import run_child  # noqa: E402
from record import commit, machine  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PACKINGS = ROOT / "benchmarks" / "results" / "packings"


def _scene(case: str):
    from dataclasses import replace

    from skfem_granular.scene import Scene

    if not case.startswith("n"):  # a bundled scene
        return replace(Scene.bundled(case), output_dir=None)
    from skfem_granular.collapse import column_scene
    from skfem_granular.packing import load_packing

    n = int(case.removeprefix("n"))
    pk = load_packing(PACKINGS / f"dense_a0.8_n{n}_seed0.npz")
    return column_scene(pk, fluid=True, core_ratio=0.9, t_end=2e-4, dt=2e-4)


def _largest_matrix(case: str):
    """(A, nu, blocks) of the largest matrix factorised in the case's first step."""
    from dataclasses import replace

    from skfem_granular.fluid.superlu import SuperLUSolver
    from skfem_granular.simulation import Simulation

    got: dict = {"A": None}
    original = SuperLUSolver.factorize

    def capture(self, A, nu, **blocks):
        if got["A"] is None or A.shape[0] > got["A"].shape[0]:
            got.update(A=A.copy(), nu=nu, blocks=dict(blocks))
        return original(self, A, nu, **blocks)

    scene = _scene(case)
    scene = replace(scene, time=replace(scene.time, t_end=scene.time.dt))
    SuperLUSolver.factorize = capture
    try:
        Simulation(scene).run(progress=False)
    finally:
        SuperLUSolver.factorize = original
    return got["A"], got["nu"], got["blocks"]


def _peak_reset() -> None:
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")


def _peak_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def child(case: str) -> dict:
    import scipy.sparse.linalg as spla

    from skfem_granular.fluid.superlu import SuperLUSolver

    A, nu, blocks = _largest_matrix(case)
    rec = {"case": case, "unknowns": A.shape[0], "velocity_unknowns": nu,
           "matrix_nnz": int(A.nnz)}
    _peak_reset()
    base = _peak_mb()
    t0 = time.process_time()
    s = SuperLUSolver().factorize(A, nu, **blocks)
    lu = s._lu.lu if hasattr(s._lu, "lu") else s._lu
    rec["static"] = {"nnz": int(lu.nnz), "cpu_s": time.process_time() - t0,
                     "peak_mb_above_start": _peak_mb() - base}
    scaled = s._with_scale(s._A).tocsc()
    del s, lu
    _peak_reset()
    base = _peak_mb()
    t0 = time.process_time()
    lu = spla.splu(scaled, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.01,
                   options=dict(SymmetricMode=True))
    rec["pivoted"] = {"nnz": int(lu.nnz), "cpu_s": time.process_time() - t0,
                      "peak_mb_above_start": _peak_mb() - base}
    rec["fill_ratio"] = rec["pivoted"]["nnz"] / rec["static"]["nnz"]
    rec["bytes_per_pivoted_entry"] = rec["pivoted"]["peak_mb_above_start"] * 2**20 / (
        rec["pivoted"]["nnz"])
    return rec


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", default="single_particle,n25,n100")
    ap.add_argument("--tag", default="default")
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        print(json.dumps(child(args.child)))
        return 0
    out = {"benchmark": "fallback_fill", "commit": commit(), "machine": machine(),
           "loadavg_start": os.getloadavg(), "cases": []}
    for case in args.cases.split(","):
        rec = run_child(__file__, case)
        out["cases"].append(rec)
        print(json.dumps(rec), flush=True)
        path = ROOT / "benchmarks" / "results" / f"fallback_fill_{args.tag}.json"
        path.write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
