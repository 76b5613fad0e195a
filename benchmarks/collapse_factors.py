"""Benchmark: what sets the dry run-out of a small column (DEM only), factor by factor.

Usage: ``python benchmarks/collapse_factors.py --shape ngon [--n 200] [--aspect 0.8]
[--seeds 0 1 2] [--mus 0.488] [--rough] [--tag NAME]``.

For every seed a dense column is prepared (:func:`skfem_granular.packing.prepare_column`;
cached as ``.npz`` under ``--cache``) and released dry in its default tank
(:func:`skfem_granular.collapse.tank_size`) with each contact friction of ``--mus``
(grain-grain and grain-wall alike; damping 0.5, the packing's stiffness), optionally on
a rough floor (``--rough``: a row of fixed half-buried 12-gons of diameter ``d_mean``,
touching, along the floor). The run goes on to ``--t-max`` tau_c or until the grains'
kinetic energy falls below 1e-4 of its peak. The front is read three ways
(:func:`skfem_granular.collapse.front_position`):

- ``gap``: the mass ends at a hole wider than the widest grain (the benchmark's rule);
- ``mass``: the farthest grain in contact with the main mass (the largest group of
  touching grains; :func:`skfem_granular.collapse.mass_front`, Kumar 2015);
- ``farthest``: the right end of the farthest grain;

and at two stops: ``E1`` the first time after 3 tau_c that the kinetic energy is below
1e-2 of its peak (the dry benchmark's rule), ``end`` at the end of the run. Writes
``benchmarks/results/collapse_factors_<tag>.json``: every run, and the mean and spread
over seeds (:func:`skfem_granular.collapse.realisations`), CPU times of the process.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from skfem_granular.collapse import (
    DRY_LAWS,
    FRICTION,
    dry_runout,
    front_position,
    mass_front,
    realisations,
    tank_size,
    time_scale,
)
from skfem_granular.dem import ContactLaw, DEMSystem, Particle, Polygon
from skfem_granular.dem.particles import pad_outlines
from skfem_granular.packing import diameter_range, load_packing, prepare_column

RESULTS = Path(__file__).resolve().parent / "results"
FRONTS = ("gap", "mass", "farthest")


def packing_for(n, aspect, shape, seed, cache: Path, E=1e6, margin=2.0):
    """The dense packing of (n, aspect, shape, seed, E), prepared once and cached."""
    cache.mkdir(parents=True, exist_ok=True)
    path = cache / f"dense_{shape}_n{n}_a{aspect:g}_s{seed}_E{E:g}_m{margin:g}.npz"
    if path.exists():
        return load_packing(path), 0.0
    c0 = time.process_time()
    p = prepare_column(n, aspect, "dense", shape=shape, seed=seed, E=E, margin=margin)
    p.save(path)
    return p, time.process_time() - c0


def rough_floor(length, d):
    """Fixed 12-gons of diameter ``d`` centred on the floor ``y = 0``, touching."""
    k = int(length // d)
    return [Polygon.regular(12, 0.5 * d, center=((i + 0.5) * d, 0.0)) for i in range(k)]


def fronts(outlines, d_min):
    """The front read the three ways of :data:`FRONTS`."""
    return {"gap": front_position(outlines),
            "mass": mass_front(outlines),
            "farthest": float(max(P[0].max() for P in outlines))}


def collapse(p, mu, rough, t_max_tau, chunk=1e-3):
    """Release ``p`` dry; the fronts at the two stops and a coarse run-out curve."""
    L, H = tank_size(p)
    tau = time_scale(p)
    d_min = diameter_range(p.d_mean, p.size_ratio)[0]
    walls = rough_floor(L, p.d_mean) if rough else []
    y0 = 0.5 * p.d_mean if rough else 0.0  # the column stands on the bumps' tops
    grains = [Particle(Polygon(P + np.array([[0.0], [y0]])), p.density, core_ratio=1.0)
              for P in p.outlines]
    law = ContactLaw(E=p.E, mu=mu, gamma=0.5)
    dem = DEMSystem.in_box(grains, (0.0, 0.0, L, H + y0), p.d_max, law=law, walls=walls,
                           overlap_tolerance=max(1e-3, 1.5 * p.max_overlap))
    peak, out, curve, k = 0.0, {}, [], 0
    while dem.t < t_max_tau * tau:
        dem.advance(chunk)
        k += 1
        E = dem.kinetic_energy()
        peak = max(peak, E)
        e1 = "E1" not in out and dem.t > 3.0 * tau and E < 1e-2 * peak
        if k % 5 == 0 or e1:
            f = fronts(dem.shadow_outlines(), d_min)
            curve.append([dem.t / tau] + [(f[c] - p.width) / p.width for c in FRONTS])
        if e1:
            out["E1"] = dict(f, t_over_tau=dem.t / tau)
        if dem.t > 3.0 * tau and E < 1e-4 * peak:
            break
    final = dem.shadow_outlines()
    f = fronts(final, d_min)
    out["end"] = dict(f, t_over_tau=dem.t / tau, E_over_peak=E / peak)
    out.setdefault("E1", None)
    for stop in ("E1", "end"):
        if out[stop] is not None:
            for k in FRONTS:
                out[stop][k] = (out[stop][k] - p.width) / p.width
    return out, curve, final


def refront(row, tag, cache: Path):
    """``row`` with the end's mass front read again from its saved final outlines (the
    current :func:`~skfem_granular.collapse.mass_front`); fronts not in :data:`FRONTS`
    dropped. Without saved outlines the row keeps no mass front."""
    for stop in ("E1", "end"):
        if row[stop] is not None:
            row[stop] = {k: v for k, v in row[stop].items() if k in FRONTS
                         or k in ("t_over_tau", "E_over_peak")}
            row[stop].pop("mass", None)
    path = cache / f"final_{tag}_s{row['seed']}_mu{row['mu']:.3g}.npz"
    if path.exists():
        with np.load(path) as z:
            final = [z["vertices"][k, : z["counts"][k]].T for k in range(len(z["counts"]))]
        row["end"]["mass"] = (mass_front(final) - row["L0"]) / row["L0"]
    return row


def summary(rows):
    """Mean and spread over seeds per (shape, mu, rough), front and stop."""
    groups = {}
    for r in rows:
        key = f"{r['shape']} n={r['n']} mu={r['mu']:.3g} rough={r['rough']}"
        groups.setdefault(key, []).append(r)
    out = {}
    for key, rs in groups.items():
        a = float(np.mean([r["aspect"] for r in rs]))
        s = {"aspect": realisations([r["aspect"] for r in rs]),
             "laws": {k: float(dry_runout(a, k)) for k in DRY_LAWS}}
        for stop in ("E1", "end"):
            ok = [r for r in rs if r[stop] is not None]
            if ok:
                s[stop] = {k: realisations([r[stop][k] for r in ok]) for k in FRONTS
                           if all(k in r[stop] for r in ok)}
        out[key] = s
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--aspect", type=float, default=0.8)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--shape", default="ngon")
    ap.add_argument("--mus", type=float, nargs="+", default=[FRICTION])
    ap.add_argument("--rough", action="store_true")
    ap.add_argument("--E", type=float, default=1e6, help="contact stiffness (N/m)")
    ap.add_argument("--margin", type=float, default=2.0,
                    help="solid fraction measured this many d_max from the edges")
    ap.add_argument("--t-max", type=float, default=20.0)
    ap.add_argument("--cache", default="/tmp/collapse_packings")
    ap.add_argument("--tag", default=None)
    ap.add_argument("--merge", nargs="+", default=None, metavar="TAG",
                    help="only merge the runs of these tags into collapse_factors_<tag>.json")
    a = ap.parse_args(argv)
    if a.merge:
        rows = [refront(r, t, Path(a.cache)) for t in a.merge for r in json.loads(
            (RESULTS / f"collapse_factors_{t}.json").read_text())["runs"]]
        out = {"benchmark": "collapse_factors", "merged": a.merge, "summary": summary(rows),
               "runs": rows}
        (RESULTS / f"collapse_factors_{a.tag}.json").write_text(json.dumps(out, indent=1))
        return
    tag = a.tag or f"{a.shape}_n{a.n}_a{a.aspect:g}"
    path = RESULTS / f"collapse_factors_{tag}.json"
    rows = []
    for seed in a.seeds:
        p, cpu_pack = packing_for(a.n, a.aspect, a.shape, seed, Path(a.cache), a.E,
                                   a.margin)
        for mu in a.mus:
            c0 = time.process_time()
            res, curve, final = collapse(p, mu, a.rough, a.t_max)
            V, counts = pad_outlines(final)
            np.savez(Path(a.cache) / f"final_{tag}_s{seed}_mu{mu:.3g}.npz", vertices=V,
                     counts=counts)
            row = {"n": a.n, "shape": a.shape, "seed": seed, "mu": mu, "rough": a.rough,
                   "aspect": p.aspect, "solid_fraction": p.solid_fraction, "L0": p.width,
                   "H0": p.height, "packing_cpu_s": cpu_pack,
                   "collapse_cpu_s": time.process_time() - c0, **res,
                   "curve_t_" + "_".join(FRONTS): curve[::5]}
            print(json.dumps({k: v for k, v in row.items() if not k.startswith("curve")}),
                  flush=True)
            rows.append(row)
            out = {"benchmark": "collapse_factors", "machine": platform.platform(),
                   "cpus": os.cpu_count(), "python": platform.python_version(),
                   "args": vars(a), "summary": summary(rows), "runs": rows}
            path.write_text(json.dumps(out, indent=1))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
