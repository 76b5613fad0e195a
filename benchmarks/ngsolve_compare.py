"""Benchmark: side by side with NGSolve on the same DFG 2D-1 meshes.

Usage::

    python benchmarks/ngsolve_compare.py --ngsolve-python /work/venv-ngsolve/bin/python \
        [--levels 0,1,2,3] [--repeats 5] [--out benchmarks/results/ngsolve_compare.json]

The DFG 2D-1 benchmark (Schaefer and Turek 1996): channel 2.2 x 0.41, cylinder of
radius 0.05 at (0.2, 0.2), nu = 1e-3, rho = 1, parabolic inflow with Um = 0.3 (Re 20),
no slip on the walls and the cylinder, do-nothing outflow (``nu grad(u) n - p n = 0``:
the Laplacian form of the viscous term, ``viscous="laplace"``, on both sides). The
cylinder is a regular polygon, so straight-sided P2 triangles are exact for both codes;
each level doubles the polygon's sides and quarters triangle's area bound. Every level's
mesh is built once (``triangle``) and handed to both codes as the same vertices,
triangles and named boundary edges (to NGSolve through ``netgen.meshing.Mesh``).
Taylor-Hood P2/P1 on both sides (NGSolve: ``VectorH1(order=2) x H1(order=1)``).

Measured, one thread each (OMP/MKL/OPENBLAS threads 1, NGSolve without TaskManager),
interleaved: both codes run in worker processes that stay alive, and every repeat asks
each contender in turn (so load changes hit all of them alike); medians over the
repeats (the first call of each, with its imports and set-up, is kept apart):

- one Stokes solve from the mesh (spaces, assembly, factorisation, solve);
- one Newton iteration at the Stokes solution (residual and Jacobian assembly,
  factorisation, solve), its parts apart; the solver objects stay alive between the
  repeats, so PARDISO's analysis (and SuperLU's ordering) is reused, NGSolve's
  ``Inverse`` analyses every time as its Newton loop does;
- a full steady Newton solve from the mesh to the same relative residual;
- peak memory: ``ru_maxrss`` of a fresh process per code, level and solver that runs the
  full steady solve (the process's resident size after its imports is given too), and
  again with glibc's mmap threshold fixed (``MALLOC_MMAP_THRESHOLD_=131072``): freed
  memory then goes back to the system at once, which shows the allocator's share;
- drag and lift coefficients ``c = 2 F / (rho U^2 D)``, ``U = 2 Um / 3``, ``D = 0.1``,
  from the momentum residual on the cylinder (both codes), against the reference.

NGSolve is an optional benchmark dependency (``pip install ngsolve``, possibly in its
own environment given by ``--ngsolve-python``), not a project dependency. The worker
mode (``--worker ours|ngsolve``) imports only its own code, so this file runs under
either interpreter. Writes the JSON (load averages, versions, commit) and prints a
markdown table.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from record import commit

LENGTH, HEIGHT = 2.2, 0.41
CENTER, RADIUS = (0.2, 0.2), 0.05
NU, UM = 1e-3, 0.3
U_MEAN, DIAMETER = 2.0 * UM / 3.0, 2.0 * RADIUS
CD_REF, CL_REF = 5.57953523384, 0.010618948146
TOL = 1e-10  # Newton: relative residual (to the zero-interior state's) or update
MAXITER = 20

#: level -> (sides of the cylinder polygon, triangle's area bound)
LEVELS = {0: (32, 0.0046), 1: (64, 0.00115), 2: (128, 0.00029), 3: (256, 0.000072)}

#: one thread everywhere
THREADS = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
           "NUMBA_NUM_THREADS": "1"}

BOUNDARIES = ("inlet", "outlet", "wall", "cylinder")
OURS = ("superlu", "pardiso")
NGSOLVE = ("umfpack", "pardiso", "sparsecholesky")

ROOT = Path(__file__).resolve().parents[1]


# the mesh ----------------------------------------------------------------------------


def dfg_mesh(level: int):
    """The level's mesh as ``(p, t, boundary edges by name)`` (0-based, ``t`` CCW)."""
    import skfem
    import triangle

    if level not in LEVELS:
        raise ValueError(f"level = {level!r}: must be one of {sorted(LEVELS)}")
    n, area = LEVELS[level]
    a = 2 * np.pi * np.arange(n) / n
    cyl = np.c_[CENTER[0] + RADIUS * np.cos(a), CENTER[1] + RADIUS * np.sin(a)]
    box = np.array([[0.0, 0.0], [LENGTH, 0.0], [LENGTH, HEIGHT], [0.0, HEIGHT]])
    ring = np.c_[np.arange(n), (np.arange(n) + 1) % n]
    pslg = dict(vertices=np.r_[box, cyl], holes=[list(CENTER)],
                segments=np.r_[[[0, 1], [1, 2], [2, 3], [3, 0]], 4 + ring])
    tri = triangle.triangulate(pslg, f"pq30a{area:.10f}")  # triangle reads no exponents
    p, t = tri["vertices"].T.copy(), tri["triangles"].T.copy()
    d = (p[0, t[1]] - p[0, t[0]]) * (p[1, t[2]] - p[1, t[0]]) - \
        (p[0, t[2]] - p[0, t[0]]) * (p[1, t[1]] - p[1, t[0]])
    t[1:, d < 0] = t[:0:-1, d < 0]
    mesh = skfem.MeshTri(p, t)
    eps = 1e-9
    tests = {"inlet": lambda x: x[0] < eps, "outlet": lambda x: x[0] > LENGTH - eps,
             "wall": lambda x: (x[1] < eps) | (x[1] > HEIGHT - eps),
             "cylinder": lambda x: np.hypot(x[0] - CENTER[0], x[1] - CENTER[1]) < 1.5 * RADIUS}
    mid = mesh.p[:, mesh.facets[:, mesh.boundary_facets()]].mean(axis=1)
    edges = {}
    for name in BOUNDARIES:
        facets = mesh.boundary_facets()[tests[name](mid)]
        edges[name] = mesh.facets[:, facets].copy()
    if sum(e.shape[1] for e in edges.values()) != mesh.boundary_facets().size:
        raise RuntimeError("dfg_mesh: a boundary edge belongs to no named boundary")
    return p, t, edges


def save_mesh(level: int, path: Path) -> dict:
    """Write the level's mesh to ``path`` (``.npz``, plain arrays); its sizes."""
    p, t, edges = dfg_mesh(level)
    np.savez(path, p=p, t=t, **{f"edge_{k}": v for k, v in edges.items()})
    n_edges = p.shape[1] + t.shape[1]  # Euler, one hole: V - E + F = 0
    return {"level": level, "polygon_sides": LEVELS[level][0], "max_area": LEVELS[level][1],
            "vertices": int(p.shape[1]), "triangles": int(t.shape[1]),
            "dofs": int(2 * (p.shape[1] + n_edges) + p.shape[1])}


def load_mesh(path: str) -> tuple:
    z = np.load(path)
    return z["p"], z["t"], {k: z[f"edge_{k}"] for k in BOUNDARIES}


def inflow(x, y):
    """Parabolic inflow ``(4 Um y (H - y) / H^2, 0)``."""
    return 4.0 * UM * y * (HEIGHT - y) / HEIGHT**2, 0.0 * y


def coefficients(force) -> tuple[float, float]:
    """Drag and lift coefficients of a force ``(Fx, Fy)`` (rho = 1)."""
    scale = 2.0 / (U_MEAN**2 * DIAMETER)
    return float(force[0] * scale), float(force[1] * scale)


# our code ----------------------------------------------------------------------------


class Ours:
    """skfem-granular on one mesh: Stokes, Newton iterations, steady solves."""

    def __init__(self, path: str):
        import skfem

        p, t, edges = load_mesh(path)
        mesh = skfem.MeshTri(p, t)
        index = {tuple(sorted(e)): k for k, e in enumerate(mesh.facets.T)}
        self.mesh = mesh.with_boundaries(
            {name: np.array([index[tuple(sorted(e))] for e in edges[name].T])
             for name in BOUNDARIES})
        self.velocity = {"inlet": inflow, "wall": (0.0, 0.0), "cylinder": (0.0, 0.0)}
        self.newton = {}  # solver name -> (operator, state, solver object)

    def _fluid(self):
        import skfem_granular as sg

        return sg.Fluid(1.0, NU)

    def stokes(self, solver: str) -> dict:
        import skfem_granular as sg

        t0 = time.perf_counter()
        space = sg.TaylorHood(self.mesh)
        t1 = time.perf_counter()
        flow = sg.solve_steady(space, self._fluid(), self.velocity, viscous="laplace",
                               solver=solver)
        total = time.perf_counter() - t0
        w, st = flow.report.wall_time, flow.report.solver
        return {"total": total, "space": t1 - t0, "assembly": w["setup"] + w["assembly"],
                "factor": st["time_factor"], "solve": st["time_solve"], "dofs": int(space.N)}

    def newton_iteration(self, solver: str) -> dict:
        import skfem_granular as sg
        from skfem_granular.fluid.boundary import DirichletData
        from skfem_granular.fluid.linsolve import make_solver
        from skfem_granular.fluid.operator import NavierStokesOperator

        if solver not in self.newton:
            space = sg.TaylorHood(self.mesh)
            x0 = sg.solve_steady(space, self._fluid(), self.velocity, viscous="laplace",
                                 solver="superlu").x
            op = NavierStokesOperator(space, self._fluid(), DirichletData(space, self.velocity),
                                      convection=True, viscous="laplace")
            self.newton[solver] = (op, x0, make_solver(solver))
        op, x0, lin = self.newton[solver]
        x = x0.copy()
        t0 = time.perf_counter()
        r = op.residual(x)
        J = op.reduced_jacobian(x)
        t1 = time.perf_counter()
        lin.factorize(J, op.nu_free, **op.solver_blocks())
        t2 = time.perf_counter()
        x[op.free] += lin.solve_correction(-r[op.free])
        t3 = time.perf_counter()
        return {"total": t3 - t0, "assembly": t1 - t0, "factor": t2 - t1, "solve": t3 - t2}

    def steady(self, solver: str) -> dict:
        import skfem_granular as sg

        t0 = time.perf_counter()
        flow = sg.solve_steady(sg.TaylorHood(self.mesh), self._fluid(), self.velocity, True,
                               viscous="laplace", solver=solver, tol=TOL, maxiter=MAXITER,
                               continuation="off")
        total = time.perf_counter() - t0
        cd, cl = coefficients(flow.force("cylinder"))
        w, st = flow.report.wall_time, flow.report.solver
        return {"total": total, "iterations": flow.report.iterations, "cd": cd, "cl": cl,
                "assembly": w["setup"] + w["assembly"], "factor": st["time_factor"],
                "solve": st["time_solve"], "residual": flow.report.residuals[-1]}


# NGSolve -----------------------------------------------------------------------------


def netgen_mesh(path: str):
    """The mesh as an ``ngsolve.Mesh``: same vertices, triangles and boundary edges."""
    import ngsolve
    from netgen.meshing import Element1D, Element2D, FaceDescriptor, MeshPoint, Pnt
    from netgen.meshing import Mesh as NetgenMesh

    p, t, edges = load_mesh(path)
    m = NetgenMesh(dim=2)
    ids = [m.Add(MeshPoint(Pnt(float(x), float(y), 0.0))) for x, y in p.T]
    fd = m.Add(FaceDescriptor(surfnr=1, domin=1, bc=1))
    m.SetMaterial(fd, "fluid")
    for tri in t.T:
        m.Add(Element2D(fd, [ids[i] for i in tri]))
    for k, name in enumerate(BOUNDARIES, start=1):
        for a, b in edges[name].T:
            m.Add(Element1D([ids[a], ids[b]], index=k))
        m.SetBCName(k - 1, name)
    return ngsolve.Mesh(m)


class NGSolveCase:
    """NGSolve on one mesh, the same problems as :class:`Ours`."""

    def __init__(self, path: str):
        self.mesh = netgen_mesh(path)
        self.newton = {}

    def _setup(self):
        import ngsolve as ngs

        V = ngs.VectorH1(self.mesh, order=2, dirichlet="inlet|wall|cylinder")
        Q = ngs.H1(self.mesh, order=1)
        X = V * Q
        (u, p), (v, q) = X.TnT()
        stokes = (NU * ngs.InnerProduct(ngs.grad(u), ngs.grad(v)) - ngs.div(u) * q
                  - ngs.div(v) * p) * ngs.dx
        gfu = ngs.GridFunction(X)
        y = ngs.y
        gfu.components[0].Set(ngs.CF((4 * UM * y * (HEIGHT - y) / HEIGHT**2, 0)),
                              definedon=self.mesh.Boundaries("inlet"))
        return X, u, v, stokes, gfu

    def _stokes(self, X, stokes, gfu, inverse):
        import ngsolve as ngs

        t0 = time.perf_counter()
        a = ngs.BilinearForm(X)
        a += stokes
        a.Assemble()
        res = gfu.vec.CreateVector()
        res.data = -a.mat * gfu.vec
        t1 = time.perf_counter()
        inv = a.mat.Inverse(X.FreeDofs(), inverse=inverse)
        t2 = time.perf_counter()
        gfu.vec.data += inv * res
        t3 = time.perf_counter()
        return {"assembly": t1 - t0, "factor": t2 - t1, "solve": t3 - t2}

    def stokes(self, solver: str) -> dict:
        t0 = time.perf_counter()
        X, u, v, stokes, gfu = self._setup()
        t1 = time.perf_counter()
        out = self._stokes(X, stokes, gfu, solver)
        out["assembly"] += t1 - t0
        out["total"] = time.perf_counter() - t0
        out["dofs"] = X.ndof
        return out

    def _navier_stokes(self, X, u, v, stokes):
        import ngsolve as ngs

        n = ngs.BilinearForm(X)
        n += stokes + ngs.InnerProduct(ngs.grad(u) * u, v) * ngs.dx
        return n

    def _iteration(self, X, n, gfu, inverse, res, du):
        t0 = time.perf_counter()
        n.Apply(gfu.vec, res)
        n.AssembleLinearization(gfu.vec)
        t1 = time.perf_counter()
        inv = n.mat.Inverse(X.FreeDofs(), inverse=inverse)
        t2 = time.perf_counter()
        du.data = inv * res
        gfu.vec.data -= du
        t3 = time.perf_counter()
        return {"total": t3 - t0, "assembly": t1 - t0, "factor": t2 - t1, "solve": t3 - t2}

    def newton_iteration(self, solver: str) -> dict:
        if solver not in self.newton:
            X, u, v, stokes, gfu = self._setup()
            self._stokes(X, stokes, gfu, "umfpack")
            n = self._navier_stokes(X, u, v, stokes)
            self.newton[solver] = (X, n, gfu, gfu.vec.CreateVector())
        X, n, gfu, x0 = self.newton[solver]
        x0.data = gfu.vec
        out = self._iteration(X, n, gfu, solver, gfu.vec.CreateVector(),
                              gfu.vec.CreateVector())
        gfu.vec.data = x0
        return out

    def steady(self, solver: str) -> dict:
        import ngsolve as ngs

        t0 = time.perf_counter()
        X, u, v, stokes, gfu = self._setup()
        n = self._navier_stokes(X, u, v, stokes)
        free = np.array(list(X.FreeDofs()), dtype=bool)
        res, du = gfu.vec.CreateVector(), gfu.vec.CreateVector()
        n.Apply(gfu.vec, res)
        ref = max(np.linalg.norm(res.FV().NumPy()[free]), 1e-300)
        parts = self._stokes(X, stokes, gfu, solver if solver != "sparsecholesky" else "umfpack")
        parts["assembly"] += 0.0
        its, rel = 1, np.inf
        while its < MAXITER:
            its += 1
            step = self._iteration(X, n, gfu, solver, res, du)
            for k in ("assembly", "factor", "solve"):
                parts[k] += step[k]
            t1 = time.perf_counter()
            n.Apply(gfu.vec, res)
            parts["assembly"] += time.perf_counter() - t1
            rel = np.linalg.norm(res.FV().NumPy()[free]) / ref
            size = np.linalg.norm(du.FV().NumPy()[free]) / max(
                np.linalg.norm(gfu.vec.FV().NumPy()[free]), 1e-300)
            if rel <= TOL or size <= TOL:
                break
        total = time.perf_counter() - t0
        force = []
        for e in ((1.0, 0.0), (0.0, 1.0)):
            w = ngs.GridFunction(X)
            w.components[0].Set(ngs.CF(e), definedon=self.mesh.Boundaries("cylinder"))
            force.append(-ngs.InnerProduct(res, w.vec))
        cd, cl = coefficients(force)
        return {"total": total, "iterations": its, "cd": cd, "cl": cl, "residual": float(rel),
                **{k: parts[k] for k in ("assembly", "factor", "solve")}}


def ngsolve_inverses(case: NGSolveCase) -> list[str]:
    """The ``inverse=`` types this NGSolve build has, tried on the Stokes matrix."""
    import ngsolve as ngs

    X, u, v, stokes, gfu = case._setup()
    a = ngs.BilinearForm(X)
    a += stokes
    a.Assemble()
    have = []
    for name in NGSOLVE:
        try:
            inv = a.mat.Inverse(X.FreeDofs(), inverse=name)
            x = gfu.vec.CreateVector()
            x.data = inv * gfu.vec
        except Exception:  # noqa: BLE001 - any failure means: not in this build
            continue
        have.append(name)
    return have


# workers -----------------------------------------------------------------------------


def serve(code: str) -> None:
    """Answer JSON requests on stdin, one JSON line each on the original stdout."""
    out = os.fdopen(os.dup(1), "w")
    os.dup2(2, 1)  # library chatter goes to stderr
    cases, cls = {}, Ours if code == "ours" else NGSolveCase
    for line in sys.stdin:
        req = json.loads(line)
        try:
            if req["task"] == "load":
                cases[req["mesh"]] = cls(req["mesh"])
                reply = {"ok": True}
                if code == "ngsolve":
                    reply["inverses"] = ngsolve_inverses(cases[req["mesh"]])
                    import ngsolve

                    reply["version"] = ngsolve.__version__
            elif req["task"] == "drop":
                cases.pop(req["mesh"], None)
                reply = {"ok": True}
            else:
                reply = getattr(cases[req["mesh"]], req["task"])(req["solver"])
        except Exception as exc:  # noqa: BLE001 - reported to the driver
            reply = {"error": f"{type(exc).__name__}: {exc}"}
        out.write(json.dumps(reply) + "\n")
        out.flush()


def peak(code: str, mesh: str, solver: str) -> None:
    """One full steady solve in this fresh process; print the peak resident size."""
    if code == "ours":
        import skfem_granular  # noqa: F401
    else:
        import ngsolve  # noqa: F401
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    case = (Ours if code == "ours" else NGSolveCase)(mesh)
    res = case.steady(solver)
    res["maxrss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    res["after_imports_mb"] = base / 1024
    print(json.dumps(res))


class Worker:
    """A worker process of this script under some interpreter."""

    def __init__(self, python: str, code: str):
        env = dict(os.environ, **THREADS)
        env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
        self.proc = subprocess.Popen([python, __file__, "--worker", code], env=env,
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)

    def ask(self, **req) -> dict:
        self.proc.stdin.write(json.dumps(req) + "\n")
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError(f"worker ended on {req}")
        reply = json.loads(line)
        if "error" in reply:
            raise RuntimeError(f"{req}: {reply['error']}")
        return reply

    def close(self):
        self.proc.stdin.close()
        self.proc.wait(timeout=60)


#: glibc's mmap threshold fixed at its initial 128 KiB (it otherwise grows to 32 MiB as large
#: blocks are freed, and freed heap memory stays resident): what the peak is without that
FIXED_MMAP = {"MALLOC_MMAP_THRESHOLD_": "131072"}


def measure_peak(python: str, code: str, mesh: str, solver: str, extra_env=None) -> dict:
    env = dict(os.environ, **THREADS, **(extra_env or {}))
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    res = subprocess.run([python, __file__, "--peak", code, mesh, solver], env=env,
                         capture_output=True, text=True, timeout=1800, check=True)
    return json.loads(res.stdout.strip().splitlines()[-1])


# the driver --------------------------------------------------------------------------


def median_parts(runs: list[dict]) -> dict:
    keys = [k for k, v in runs[0].items() if isinstance(v, float)]
    return {k: statistics.median(r[k] for r in runs) for k in keys} | {"runs": runs}


def bench_level(level, tmp, workers, ng_inverses, repeats) -> dict:
    path = str(tmp / f"dfg_{level}.npz")
    info = save_mesh(level, Path(path))
    for w in workers.values():
        w.ask(task="load", mesh=path)
    newton_ng = [s for s in ng_inverses if s != "sparsecholesky"]  # Jacobian not symmetric
    contenders = {
        "stokes": [("ngsolve", s) for s in ng_inverses] + [("ours", s) for s in OURS],
        "newton_iteration": [("ngsolve", s) for s in newton_ng] + [("ours", s) for s in OURS],
        "steady": [("ngsolve", s) for s in newton_ng] + [("ours", s) for s in OURS],
    }
    out = {"mesh": info}
    for task, cont in contenders.items():
        runs = {f"{c}/{s}": [] for c, s in cont}
        # first calls apart: imports, compilation, analyses and orderings kept after
        warm = {f"{c}/{s}": workers[c].ask(task=task, mesh=path, solver=s) for c, s in cont}
        for rep in range(repeats):
            order = cont if rep % 2 == 0 else cont[::-1]
            for c, s in order:
                runs[f"{c}/{s}"].append(workers[c].ask(task=task, mesh=path, solver=s))
        out[task] = {k: median_parts(v) for k, v in runs.items()}
        for k, v in warm.items():
            out[task][k]["first"] = v
        print(f"level {level} ({info['dofs']} DOFs) {task}: " + ", ".join(
            f"{k} {v['total']:.3f} s" for k, v in out[task].items()), flush=True)
    for w in workers.values():
        w.ask(task="drop", mesh=path)
    out["peak"] = {}
    out["peak_fixed_mmap_threshold"] = {}  # the allocator's share of the peak (see FIXED_MMAP)
    for c, s in contenders["steady"]:
        python = workers[c].proc.args[0]
        out["peak"][f"{c}/{s}"] = measure_peak(python, c, path, s)
        out["peak_fixed_mmap_threshold"][f"{c}/{s}"] = measure_peak(python, c, path, s,
                                                                    FIXED_MMAP)
    return out


def ratios(levels: dict) -> dict:
    """Ours over NGSolve's UMFPACK, per level."""
    out = {}
    for lv, r in levels.items():
        def q(task, ours, key="total", r=r):
            return r[task][f"ours/{ours}"][key] / r[task]["ngsolve/umfpack"][key]

        out[lv] = {f"{t}_{s}": q(t, s) for t in ("stokes", "newton_iteration", "steady")
                   for s in OURS}
        for s in OURS:
            for peak in ("peak", "peak_fixed_mmap_threshold"):
                if peak in r:
                    out[lv][f"{peak}_memory_{s}".replace("peak_peak", "peak")] = (
                        r[peak][f"ours/{s}"]["maxrss_mb"]
                        / r[peak]["ngsolve/umfpack"]["maxrss_mb"])
    return out


def table(res: dict) -> str:
    rows = ["| DOFs | contender | Stokes [s] | Newton iteration [s] (assembly / factor / "
            "solve) | steady Newton [s] (its) | peak memory [MB] | c_d | c_l |",
            "|---|---|---|---|---|---|---|---|"]
    for r in res["levels"].values():
        for k, it in r["newton_iteration"].items():
            st, sd, pk = r["stokes"][k], r["steady"][k], r["peak"][k]
            rows.append(
                f"| {r['mesh']['dofs']} | {k} | {st['total']:.3f} | {it['total']:.3f} "
                f"({it['assembly']:.3f} / {it['factor']:.3f} / {it['solve']:.3f}) | "
                f"{sd['total']:.3f} ({sd['runs'][0]['iterations']}) | {pk['maxrss_mb']:.0f} | "
                f"{sd['runs'][0]['cd']:.6f} | {sd['runs'][0]['cl']:.6f} |")
        for k, st in r["stokes"].items():
            if k not in r["newton_iteration"]:
                rows.append(f"| {r['mesh']['dofs']} | {k} (Stokes only) | {st['total']:.3f} "
                            "| | | | | |")
    return "\n".join(rows)


def versions(ng_version: str) -> dict:
    import scipy
    import skfem

    out = {"python": platform.python_version(), "numpy": np.__version__,
           "scipy": scipy.__version__, "scikit-fem": skfem.__version__, "ngsolve": ng_version}
    try:
        from importlib.metadata import version

        out["pypardiso"], out["mkl"] = version("pypardiso"), version("mkl")
    except Exception:  # noqa: BLE001 - optional
        pass
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--ngsolve-python", default=sys.executable)
    ap.add_argument("--levels", default="0,1,2,3")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", default=str(ROOT / "benchmarks/results/ngsolve_compare.json"))
    ap.add_argument("--worker", choices=("ours", "ngsolve"))
    ap.add_argument("--peak", nargs=3, metavar=("CODE", "MESH", "SOLVER"))
    args = ap.parse_args(argv)
    if args.worker:
        serve(args.worker)
        return 0
    if args.peak:
        peak(*args.peak)
        return 0
    try:
        levels = [int(v) for v in args.levels.split(",")]
    except ValueError:
        ap.error(f"--levels {args.levels!r}: expected comma-separated integers")
    if args.repeats < 1:
        ap.error(f"--repeats {args.repeats}: must be >= 1")
    res = {"benchmark": "DFG 2D-1 (Re 20), P2/P1 Taylor-Hood, same meshes, one thread",
           "loadavg_before": os.getloadavg(), "commit": commit(), "repeats": args.repeats,
           "threads": THREADS, "tol": TOL, "reference": {"cd": CD_REF, "cl": CL_REF},
           "machine": {"cpus": os.cpu_count(), "platform": platform.platform()}, "levels": {}}
    workers = {"ours": Worker(sys.executable, "ours"),
               "ngsolve": Worker(args.ngsolve_python, "ngsolve")}
    with tempfile.TemporaryDirectory() as tmp:
        probe = Path(tmp) / "probe.npz"
        save_mesh(levels[0], probe)
        reply = workers["ngsolve"].ask(task="load", mesh=str(probe))
        inverses = reply["inverses"]
        res["ngsolve_inverses"] = inverses
        res["versions"] = versions(reply["version"])
        for lv in levels:
            res["levels"][str(lv)] = bench_level(lv, Path(tmp), workers, inverses, args.repeats)
            res["loadavg_after_level_" + str(lv)] = os.getloadavg()
    for w in workers.values():
        w.close()
    res["ratios_to_ngsolve_umfpack"] = ratios(res["levels"])
    res["loadavg_after"] = os.getloadavg()
    text = table(res)
    res["table"] = text
    Path(args.out).write_text(json.dumps(res, indent=1) + "\n")
    print(text)
    print(json.dumps(res["ratios_to_ngsolve_umfpack"], indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
