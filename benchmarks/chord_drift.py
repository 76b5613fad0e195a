"""How fast a held Newton Jacobian goes stale in a dense immersed column, update by update.

Usage::

    python benchmarks/chord_drift.py --n 1000                     # the library's iteration
    python benchmarks/chord_drift.py --n 1000 --max-iterations 40 # a larger iteration limit
    python benchmarks/chord_drift.py --n 1000 --anderson 4        # Anderson mixing, depth 4
    python benchmarks/chord_drift.py --n 400 --steps 30 --newton-tol 1e-8 --convection off
    python benchmarks/chord_drift.py --n 400 --steps 30 --newton-tol 1e-8 --mesh-motion fixed
    python benchmarks/chord_drift.py --n 400 --steps 30 --newton-tol 1e-8 --localisation
    python benchmarks/chord_drift.py --n 25 --steps 12 --out /tmp/x.json   # quick look

``--convection off`` (unsteady Stokes) and ``--mesh-motion fixed`` (no ALE: the mesh stays
until a remesh) take away one of the two things a held Jacobian drifts with, the flow
and the moving mesh, to tell which of them makes it go stale. ``--localisation`` logs at
every refresh how few rows carry the difference between the new Jacobian and the one it
replaces.

The column of :mod:`scaling_contact` (dense, 12-gon near-disks, core ratio 0.9, steps of
0.2 ms) is released in water for ``--steps`` steps. Every update of the coupled chord
iteration (:class:`skfem_granular.coupled.monolithic.MonolithicCoupling`) is logged: its
size (largest velocity entry), the tolerance, the contraction rate against the update
before, and every refresh of the Jacobian with the rule that asked for it
(:attr:`skfem_granular.fluid.newton.ChordStall.reason`: ``ledger``, the held
factorisation's extra iterations reached the refresh price within the step, or
``ledger_at_start``, by the steps before; ``limit``, the tolerance would not be reached
within the iteration limit at the current rate; ``diverging``, rate >= 1).

Two alternatives are switches of this script only, not of the library (measured, not
kept: docs/benchmarks.md, "Why the 1000-grain column refreshes"):

- ``--max-iterations K``: the coupling's iteration limit (library: 15), so that the
  limit rule fires later and the rent-or-buy ledger decides;
- ``--anderson M``: Anderson mixing (type II, depth ``M``, least squares on the velocity
  entries) of the chord updates, its history cleared at every refresh.

Writes ``benchmarks/results/chord_drift_n<N>[_<tag>].json``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from scaling_contact import CORE_RATIO, DT, packing  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def instrument(log: list, anderson: int, max_iterations: int | None, sim_ref: dict) -> None:
    """Hook the stall rule (and, if asked, the iteration) of the coupled corrector."""
    import skfem_granular.coupled.monolithic as mono
    from skfem_granular.fluid import newton

    observe, refresh_due = newton.ChordStall.observe, newton.ChordStall.refresh_due
    state = {"refreshed": False}

    def logged_observe(self, it, dn, done, tol):
        prev = self.prev
        ledger = None if self.ledger is None else self.ledger.extra_iterations
        observe(self, it, dn, done, tol)
        log.append({"ev": "update", "it": it, "dn": dn, "tol": tol,
                    "rate": dn / prev if prev else None, "done": done, "ledger": ledger})

    def logged_refresh_due(self, it):
        r = refresh_due(self, it)
        if r:
            state["refreshed"] = True
            log.append({"ev": "refresh", "it": it, "refresh_asked": self.reason})
        return r

    newton.ChordStall.observe = logged_observe
    newton.ChordStall.refresh_due = logged_refresh_due

    if max_iterations:
        init = mono.MonolithicCoupling.__init__

        def init_with_limit(self, *a, **k):
            init(self, *a, **k)
            self.max_iterations = max_iterations

        mono.MonolithicCoupling.__init__ = init_with_limit

    if anderson > 0:
        def mixed_iterate(x, residual, correction, stop, *, max_iterations,
                          index=slice(None)):
            nu = sim_ref["sim"].coupling.nu_z
            dX, dF, x_prev, f_prev = [], [], None, None
            for it in range(1, max_iterations + 1):
                r = residual(x)
                state["refreshed"] = False
                f = correction(x, r, it)
                if state["refreshed"]:  # a new operator: the history is another map's
                    dX, dF, x_prev, f_prev = [], [], None, None
                xi = x[index].copy()
                step = f
                if f_prev is not None:
                    dX.append(xi - x_prev)
                    dF.append(f - f_prev)
                    if len(dX) > anderson:
                        dX.pop(0)
                        dF.pop(0)
                    gamma = np.linalg.lstsq(np.column_stack([d[:nu] for d in dF]), f[:nu],
                                            rcond=1e-10)[0]
                    step = f - sum(g * (a + b) for g, a, b in zip(gamma, dX, dF, strict=True))
                x_prev, f_prev = xi, f
                x[index] += step
                if stop(it, f, x):
                    return it
            return None

        mono.newton_iterate = mixed_iterate


def localisation(log: list, sim_ref: dict) -> None:
    """At every refresh, where the new Jacobian differs from the one it replaces: the
    relative size of the difference (Frobenius) and the fewest rows that carry 50, 90
    and 99 % of it, as fractions of all rows (and the share of the rigid-body rows)."""
    from skfem_granular.fluid.factor_cache import FactorCache

    factorize_system = FactorCache.factorize_system
    held: dict = {"J": None}

    def compared(self, a0, system):
        J = system[1]
        old = held["J"]
        if old is not None and old.shape == J.shape:
            D = (J - old).tocsr()
            nonempty = np.diff(D.indptr) > 0
            rows = np.add.reduceat(np.r_[D.data ** 2, 0.0], D.indptr[:-1]) * nonempty
            total = float(rows.sum())
            order = np.sort(rows)[::-1].cumsum() / total if total > 0 else np.zeros(1)
            rigid = sim_ref["sim"].coupling.rigid_slice
            size = float(np.sqrt((J.data ** 2).sum()))
            entry = {"ev": "localisation", "rel": float(np.sqrt(total)) / size,
                     "rigid_share": float(rows[rigid].sum() / total) if total > 0 else 0.0,
                     "rigid_rows": (rigid.stop - rigid.start) / J.shape[0]}
            for q in (0.5, 0.9, 0.99):
                entry[f"rows_{int(q * 100)}"] = float((np.searchsorted(order, q) + 1) / J.shape[0])
            log.append(entry)
            print(json.dumps(entry), file=sys.stderr, flush=True)
        held["J"] = J.copy()
        return factorize_system(self, a0, system)

    FactorCache.factorize_system = compared


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--steps", type=int, default=12)
    ap.add_argument("--max-iterations", type=int, default=None)
    ap.add_argument("--anderson", type=int, default=0)
    ap.add_argument("--newton-tol", type=float, default=None,
                    help="the corrector's tolerance (default: the scene's)")
    ap.add_argument("--convection", choices=("on", "off"), default="on",
                    help="off: unsteady Stokes (is the held Jacobian's drift the convection's?)")
    ap.add_argument("--mesh-motion", choices=("ale", "fixed"), default="ale",
                    help="fixed: the mesh stays until a remesh (is it the moving gaps'?)")
    ap.add_argument("--localisation", action="store_true",
                    help="at every refresh, how few rows carry the Jacobian's change")
    ap.add_argument("--tag", default=None)
    ap.add_argument("--out", default=None)
    a = ap.parse_args(argv)
    from skfem_granular.collapse import column_scene
    from skfem_granular.fluid import newton
    from skfem_granular.simulation import Simulation

    log: list = []
    sim_ref: dict = {}
    instrument(log, a.anderson, a.max_iterations, sim_ref)
    if a.localisation:
        localisation(log, sim_ref)
    pk = packing(a.n)
    scene = column_scene(pk, fluid=True, core_ratio=CORE_RATIO, t_end=a.steps * DT, dt=DT,
                         name=f"chord_drift_{a.n}")
    scene = replace(scene, mesh_motion=a.mesh_motion,
                    effects=replace(scene.effects, convection=a.convection == "on"),
                    **({} if a.newton_tol is None else {"newton_tol": a.newton_tol}))
    t0, c0 = time.perf_counter(), time.process_time()
    sim = sim_ref["sim"] = Simulation(scene)
    start = len(log)
    for t, step in sim.evolve():
        log.append({"ev": "step", "t": t, "iterations": step.iterations,
                    "wall_s": time.perf_counter() - t0})
        print(json.dumps(log[-1]), file=sys.stderr, flush=True)
    steps = [e for e in log[start:] if e["ev"] == "step"]
    asked = [e["refresh_asked"] for e in log if e.get("refresh_asked")]
    rec = {"benchmark": "chord_drift", "grains": a.n, "dofs": int(sim.space.N),
           "steps": len(steps), "dt": DT, "max_iterations": a.max_iterations or 15,
           "anderson": a.anderson, "refresh_iterations": newton.REFRESH_ITERATIONS,
           "newton_tol": scene.newton_tol, "convection": a.convection,
           "mesh_motion": a.mesh_motion, "remeshes": int(sim.stepper.remeshes),
           "iterations": [e["iterations"] for e in steps],
           "iterations_total": sum(e["iterations"] for e in steps),
           "refreshes": sum(e["ev"] == "refresh" for e in log),
           "refreshes_by_rule": {k: asked.count(k) for k in sorted(set(asked))},
           "wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0,
           "phases_s": sim.result.summary.get("wall_time"), "log": [
               {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                for k, v in e.items()} for e in log]}
    out = Path(a.out) if a.out else ROOT / "benchmarks/results" / (
        f"chord_drift_n{a.n}" + (f"_{a.tag}" if a.tag else "") + ".json")
    out.write_text(json.dumps(rec, indent=1) + "\n")
    print(json.dumps({k: v for k, v in rec.items() if k != "log"}))


if __name__ == "__main__":
    main()
