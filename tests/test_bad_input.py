"""Bad input across the library: one clear line naming the field, never a deep traceback.

Two tables:

* ``CLI``: a TOML scene (or a command line) that ``skfem-granular run`` must
  refuse with exit code 2 and exactly one stderr line naming the field and
  the allowed range;
* ``LIB``: library calls that cannot be written as TOML (non-mesh objects,
  boundary names, wrong types); each must raise :class:`ValueError` with one
  line naming the field, raised from project code (not from inside numpy,
  scipy or triangle).
"""

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import meshing
from skfem_granular.cli import main
from skfem_granular.dem import ContactLaw, DEMSystem, Particle, Polygon
from skfem_granular.fluid import Fluid, TaylorHood, solve_steady
from skfem_granular.fluid.unsteady import BDF2Integrator, evolve
from skfem_granular.scene import Effects, MeshSpec, ParticleSpec, Scene, TimeSpec
from skfem_granular.simulation import Simulation
from skfem_granular.studies import CollapseRun, run_collapse_study

ROOT = Path(__file__).resolve().parents[1]
PROJECT_DIRS = (str(ROOT / "skfem_granular"), str(ROOT / "meshing"))

# ---------------------------------------------------------------- TOML pieces
DOMAIN = "[domain]\nbox = [0.0, 0.0, 3.0e-3, 11.0e-3]\n"
FLUID = "[fluid]\ndensity = 1000.0\nviscosity = 1.0e-3\n"
TIME = "[time]\nt_end = 2.0e-5\ndt = 1.0e-5\n"


def particle(center="[1.5e-3, 5.5e-3]", sides=24, extra=""):
    return (
        f"[[particles]]\nsides = {sides}\nradius = 0.5e-3\ncenter = {center}\n"
        f"density = 2650.0\n{extra}"
    )


def vertices(xs, ys, extra=""):
    return f"[[particles]]\nvertices = [{xs}, {ys}]\ndensity = 2650.0\n{extra}"


def scene(*sections, top="", domain=DOMAIN, fluid=FLUID, time=TIME, particles=None):
    """A valid scene (the paper's single particle, 2 steps) with ``sections`` added.

    A section given here replaces the default of the same name; ``top`` holds
    top-level keys, which TOML needs before the first table.
    """
    parts = [top, domain, fluid, particle() if particles is None else particles]
    names = {s.split("]")[0].strip("[") for s in sections if s.startswith("[")}
    if "time" not in names:
        parts.append(time)
    return "".join(parts) + "".join(sections)


# (id, scene text or None for the command line alone, extra CLI args, expected substrings)
CLI = [
    ("dt-negative", scene("[time]\nt_end = 1e-3\ndt = -1.0\n"), [], ["time.dt = -1.0", "> 0"]),
    ("dt-zero", scene("[time]\nt_end = 1e-3\ndt = 0.0\n"), [], ["time.dt = 0.0", "> 0"]),
    ("t_end-nan", scene("[time]\nt_end = nan\n"), [], ["time.t_end = nan", "finite number > 0"]),
    ("t_end-inf", scene("[time]\nt_end = inf\n"), [], ["time.t_end = inf", "finite number > 0"]),
    ("end-before-start", scene("[time]\nt_end = -1e-3\ndt = 1e-5\n"), [],
     ["time.t_end = -0.001", "> 0"]),
    ("dt-longer-than-run", scene("[time]\nt_end = 1e-5\ndt = 1e-3\n"), [],
     ["time.dt = 0.001", "<= time.t_end"]),
    ("dt-string", scene("[time]\nt_end = 1e-3\ndt = 'fast'\n"), [], ["time.dt = 'fast'", "> 0"]),
    ("tol-zero", scene("[time]\nt_end = 1e-3\ndt = 1e-5\nadaptive = true\ntol = 0.0\n"), [],
     ["time.tol = 0.0", "> 0 and <= 1"]),
    ("tol-nan", scene("[time]\nt_end = 1e-3\ndt = 1e-5\ntol = nan\n"), [],
     ["time.tol = nan", "> 0 and <= 1"]),
    ("adaptive-string", scene("[time]\nt_end = 1e-3\ndt = 1e-5\nadaptive = 'yes'\n"), [],
     ["time.adaptive = 'yes'", "true or false"]),
    ("contact_warning-string", scene("[time]\nt_end = 1e-3\ndt = 1e-5\ncontact_warning = 'no'\n"),
     [], ["time.contact_warning = 'no'", "true or false"]),
    ("dt_min-above-dt", scene("[time]\nt_end = 1e-3\ndt = 1e-5\ndt_min = 1e-4\n"), [],
     ["time.dt_min = 0.0001", "<= time.dt"]),
    ("dem_dt-unstable", scene("[time]\nt_end = 1e-3\ndt = 1e-5\ndem_dt = 1.0\n"), [],
     ["time.dem_dt = 1", "must be <= 4.5"]),
    ("fluid-density-zero", scene(fluid="[fluid]\ndensity = 0.0\nviscosity = 1e-3\n"), [],
     ["fluid.density = 0.0", "> 0"]),
    ("viscosity-minus-inf", scene(fluid="[fluid]\ndensity = 1000.0\nviscosity = -inf\n"), [],
     ["fluid.viscosity = -inf", "> 0"]),
    ("fluid-unknown-key", scene(fluid="[fluid]\ndensity = 1000.0\nviscosty = 1e-3\n"), [],
     ["fluid: unknown key 'viscosty'", "allowed keys are density, viscosity"]),
    ("unknown-effect", scene("[effects]\nwarp = true\n"), [],
     ["effects: unknown key 'warp'", "allowed keys are contacts, convection"]),
    ("effect-not-bool", scene("[effects]\nconvection = 'yes'\n"), [],
     ["effects.convection = 'yes'", "true or false"]),
    ("contacts-effect", scene("[effects]\ncontacts = 'maybe'\n"), [],
     ["effects.contacts = 'maybe'", "true, false or 'auto'"]),
    ("unknown-section", scene("[nonsense]\na = 1\n"), [],
     ["scene: unknown key 'nonsense'", "allowed keys are column, contacts"]),
    ("unknown-particle-key", scene(particles=particle(extra="mass = 1.0\n")), [],
     ["particles[0]: unknown key 'mass'", "allowed keys are angle"]),
    ("malformed-table-header", scene("[time\nt_end = 1\n", time=""), [],
     ["scene file", "not valid TOML", "Expected ']'", "line"]),
    ("unclosed-array", scene(domain="[domain]\nbox = [0.0, 0.0, 3e-3\n"), [],
     ["scene file", "not valid TOML"]),
    ("duplicate-table", scene(DOMAIN), [], ["not valid TOML", "domain"]),
    ("particles-single-brackets", scene(particles="[particles]\nsides = 6\n"), [],
     ["particles: must be an array of tables", "[[particles]]"]),
    ("section-not-a-table", scene(top="time = 5\n", time=""), [],
     ["time = 5", "must be a table"]),
    ("non-convex-vertices",
     scene(particles=vertices("[1e-3, 2e-3, 1.5e-3, 2e-3, 1e-3]",
                              "[5e-3, 5e-3, 5.5e-3, 6e-3, 6e-3]")),
     [], ["particles[0].vertices", "strictly convex", "must be > 0"]),
    ("clockwise-vertices",
     scene(particles=vertices("[1e-3, 1e-3, 2e-3, 2e-3]", "[5e-3, 6e-3, 6e-3, 5e-3]")),
     [], ["particles[0]", "signed area", "must be > 0", "counter-clockwise"]),
    ("vertices-as-points",
     scene(particles="[[particles]]\nvertices = [[1e-3, 5e-3], [2e-3, 5e-3], [2e-3, 6e-3]]\n"
                     "density = 2650.0\n"),
     [], ["particles[0].vertices has shape (3, 2)", "must be (2, N)"]),
    ("vertices-ragged", scene(particles=vertices("[1e-3, 2e-3, 3e-3]", "[5e-3, 6e-3]")), [],
     ["particles[0].vertices", "must be a (2, N) array of numbers"]),
    ("vertices-nan", scene(particles=vertices("[1e-3, 2e-3, nan]", "[5e-3, 5e-3, 6e-3]")), [],
     ["particles[0].vertices", "must be finite"]),
    ("overlapping-particles", scene(particles=particle() + particle(center="[1.5e-3, 5.8e-3]")),
     [], ["particles[0] and particles[1] overlap", "must be <= overlap_tolerance"]),
    ("particle-outside-domain", scene(particles=particle(center="[0.2e-3, 5.5e-3]")), [],
     ["particles[0]", "sticks out of domain.box [0.0, 0.0, 0.003, 0.011]"]),
    ("grid-spacing-overlaps",
     scene(particles="", time=TIME + "[grid]\nnx = 2\nny = 1\nradius = 0.5e-3\n"
                                     "spacing = 0.5e-3\norigin = [1e-3, 2e-3]\n"),
     [], ["grid.spacing = 0.0005", "> 0.001"]),
    ("delta_l-larger-than-particle", scene("[mesh]\nkind = 'graded'\ndelta_l = 2e-3\n"), [],
     ["delta_l", "must be <= 0.0005", "particles[0]"]),
    ("4-gon-graded", scene("[mesh]\nkind = 'graded'\n", particles=particle(sides=4)), [],
     ["particles[0]: outline edges", "pass delta_l <= 0.000309"]),
    ("uniform-h-too-big", scene("[mesh]\nkind = 'uniform'\nh = 1.0\n"), [],
     ["h: must be in (0, 0.0015]", "got 1.0"]),
    ("mesh-kind", scene("[mesh]\nkind = 'hex'\n"), [],
     ["mesh.kind = 'hex'", "'graded', 'uniform' or 'group'"]),
    ("sigma-out-of-range", scene("[mesh]\nsigma = 2.0\n"), [], ["mesh.sigma = 2.0", "<= 1.6"]),
    ("gap-spacing-too-fine", scene("[mesh]\ngap_spacing = 0.01\n"), [],
     ["mesh.gap_spacing = 0.01", ">= 0.1"]),
    ("gap-spacing-graded", scene("[mesh]\nkind = 'graded'\ngap_spacing = 1.0\n"), [],
     ["mesh.gap_spacing", "only for kind 'field'"]),
    ("coupling-scheme", scene("[coupling]\nscheme = 'magic'\n"), [],
     ["coupling.scheme = 'magic'", "'monolithic', 'split' or 'partitioned'"]),
    ("mesh-repair", scene("[coupling]\nmesh_repair = 'smooth'\n"), [],
     ["coupling.mesh_repair = 'smooth'", "'auto', 'flips' or 'none'"]),
    ("remesh_fraction-zero", scene("[coupling]\nremesh_fraction = 0.0\n"), [],
     ["coupling.remesh_fraction = 0.0", "> 0 and <= 1"]),
    ("newton_tol-loose", scene("[coupling]\nnewton_tol = 0.01\n"), [],
     ["coupling.newton_tol = 0.01", "> 0 and <= 0.001"]),
    ("box-inverted", scene(domain="[domain]\nbox = [0.0, 0.0, -1.0, 1.0]\n"), [],
     ["domain.box", "x1 > x0, y1 > y0"]),
    ("box-three-numbers", scene(domain="[domain]\nbox = [0.0, 0.0, 1.0]\n"), [],
     ["domain.box", "must be 4 finite numbers"]),
    ("wall_thickness-zero",
     scene(domain="[domain]\nbox = [0.0, 0.0, 3e-3, 11e-3]\nwall_thickness = 0.0\n"), [],
     ["domain.wall_thickness = 0.0", "> 0"]),
    ("sides-two", scene(particles=particle(sides=2)), [],
     ["particles[0].sides = 2", "integer in [3, 1000]"]),
    ("sides-huge", scene(particles=particle(sides=10**9)), [],
     ["particles[0].sides = 1000000000", "integer in [3, 1000]"]),
    ("radius-negative", scene(particles=particle().replace("0.5e-3", "-0.5e-3")), [],
     ["particles[0].radius = -0.0005", "> 0"]),
    ("radius-below-round-off", scene(particles=particle().replace("0.5e-3", "1e-19")), [],
     ["particles[0].radius = 1e-19", "edges must have length > 0"]),
    ("coordinates-overflow",
     scene(domain="[domain]\nbox = [0.0, 0.0, 3e200, 11e200]\n",
           particles=particle(center="[1.5e200, 5.5e200]").replace("0.5e-3", "0.5e200")),
     [], ["domain.box = [0.0, 0.0, 3e+200, 1.1e+201]", "within +-1000"]),
    ("radius-overflow", scene(particles=particle().replace("0.5e-3", "0.5e200")), [],
     ["particles[0].radius = 5e+199", "<= 1000"]),
    ("density-missing", scene(particles=particle().replace("density = 2650.0\n", "")), [],
     ["particles[0].density: missing", "> 0"]),
    ("density-bool", scene(particles=particle().replace("2650.0", "true")), [],
     ["particles[0].density = True", "> 0"]),
    ("core_ratio-above-one", scene(particles=particle(extra="core_ratio = 1.5\n")), [],
     ["particles[0].core_ratio = 1.5", "> 0 and <= 1"]),
    ("core_ratio-tiny", scene(particles=particle(extra="core_ratio = 1e-9\n")), [],
     ["particles[0]: extent", "below 1e-05 x the domain size"]),
    ("velocity-nan", scene(particles=particle(extra="velocity = [nan, 0.0]\n")), [],
     ["particles[0].velocity", "2 finite numbers"]),
    ("gravity-nan", scene(top="gravity = [0.0, nan]\n"), [],
     ["gravity = [0.0, nan]", "2 finite numbers"]),
    ("no-particles", scene(particles=""), [], ["particles", "at least one particle"]),
    ("grid-nx-zero",
     scene(particles="", time=TIME + "[grid]\nnx = 0\nny = 1\nradius = 0.5e-3\n"
                                     "origin = [1e-3, 2e-3]\n"),
     [], ["grid.nx = 0", "integer in [1, 100]"]),
    ("grid-seed-string",
     scene(particles="", time=TIME + "[grid]\nnx = 1\nny = 1\nradius = 0.5e-3\n"
                                     "origin = [1.5e-3, 2e-3]\nseed = 'x'\n"),
     [], ["grid.seed = 'x'", "integer >= 0"]),
    ("contacts-E-zero", scene("[contacts]\nE = 0.0\n"), [], ["contacts.E = 0.0", "> 0"]),
    ("contacts-mu-negative", scene("[contacts]\nmu = -1.0\n"), [], ["contacts.mu = -1.0", ">= 0"]),
    ("contacts-E-string", scene("[contacts]\nE = 'stiff'\n"), [], ["contacts.E = 'stiff'", "> 0"]),
    ("vtu_every-negative", scene("[output]\nvtu_every = -1\n"), [],
     ["output.vtu_every = -1", "integer >= 0"]),
    ("output-directory-int", scene("[output]\ndirectory = 5\n"), [],
     ["output.directory = 5", "must be a string"]),
    ("output-directory-under-file", scene("[output]\ndirectory = '{FILE}/sub'\n"), ["NO-OUT"],
     ["output.directory", "must be a writable directory", "Not a directory"]),
    ("cli-out-under-file", scene(), ["--out", "{FILE}/sub"],
     ["--out = ", "must be a writable directory", "Not a directory"]),
    ("cli-out-is-file", scene(), ["--out", "{FILE}"],
     ["--out = ", "must be a writable directory", "is not a directory"]),
    ("cli-dt-negative", scene(), ["--dt", "-1"], ["time.dt = -1.0", "> 0"]),
    ("cli-t_end-before-start", scene(), ["--t-end", "-1"], ["time.t_end = -1.0", "> 0"]),
    ("cli-dt-not-a-number", scene(), ["--dt", "abc"],
     ["argument --dt: invalid float value: 'abc'"]),
    ("cli-mesh-choice", scene(), ["--mesh", "hex"], ["argument --mesh: invalid choice: 'hex'"]),
    # bounds on every input: absurd values and runaway budgets, refused before any work
    ("fluid-density-huge", scene(fluid="[fluid]\ndensity = 1e300\nviscosity = 1e-3\n"), [],
     ["fluid.density = 1e+300", "<= 100000 kg/m^3"]),
    ("viscosity-huge", scene(fluid="[fluid]\ndensity = 1000.0\nviscosity = 1e300\n"), [],
     ["fluid.viscosity = 1e+300", "must be in [1e-09, 1e+09] Pa s"]),
    ("t_end-huge", scene("[time]\nt_end = 1e300\ndt = 1e-5\n"), [],
     ["time.t_end / time.dt = 1e+300 / 1e-05", "more than max_steps = 1e+05", "--max-steps"]),
    ("dt-tiny", scene("[time]\nt_end = 1e-3\ndt = 1e-9\n"), [],
     ["= 1e+06 steps", "more than max_steps = 1e+05", "--max-steps"]),
    ("cli-max-steps-lower", scene(), ["--max-steps", "1"],
     ["= 2 steps", "more than max_steps = 1", "--max-steps"]),
    ("cli-max-steps-negative", scene(), ["--max-steps", "-1"],
     ["max_steps (--max-steps) = -1.0", "finite number >= 1"]),
    ("graded-delta_l-tiny", scene("[mesh]\nkind = 'graded'\ndelta_l = 1e-7\n"), [],
     ["mesh.delta_l = 1e-07", "about 6.78e+08 triangles", "max_elements = 2e+06",
      "--max-elements"]),
    ("uniform-h-small-memory", scene("[mesh]\nkind = 'uniform'\nh = 1e-5\n"),
     ["--max-memory", "8"],
     ["mesh.h = 1e-05", "unknowns (monolithic coupling) would need about",
      "more than max_memory = 8 GB", "--max-memory"]),
    ("cli-max-memory-lower", scene(), ["--max-memory", "0.001"],
     ["unknowns (monolithic coupling) would need about", "more than max_memory = 0.001 GB"]),
    ("cli-max-memory-negative", scene(), ["--max-memory", "-1"],
     ["--max-memory = -1.0", "must be a finite number in [0.001, 1e+06]"]),
    ("cli-max-memory-huge", scene(), ["--max-memory", "1e300"],
     ["--max-memory = 1e+300", "must be a finite number in [0.001, 1e+06]"]),
    ("too-many-particles",
     scene(time=TIME + "[grid]\nnx = 100\nny = 100\nradius = 0.5e-3\n"
           "origin = [1e-3, 1e-3]\n"),
     [], ["particles: 10001 in the scene", "at most 10000"]),
    ("angle-huge", scene(particles=particle(extra="angle = 1e300\n")), [],
     ["particles[0].angle = 1e+300", ">= -1000 and <= 1000"]),
    ("domain-box-huge", scene(domain="[domain]\nbox = [0.0, 0.0, 3.0e-3, 1e300]\n"), [],
     ["domain.box = [0.0, 0.0, 0.003, 1e+300]", "4 finite numbers within +-1000"]),
    ("wall_thickness-huge",
     scene(domain="[domain]\nbox = [0.0, 0.0, 3.0e-3, 11.0e-3]\nwall_thickness = 1e300\n"),
     [], ["domain.wall_thickness = 1e+300", "<= 1000"]),
    ("grid-spacing-huge",
     scene(particles="", time=TIME + "[grid]\nnx = 2\nny = 1\nradius = 0.5e-3\n"
           "spacing = 1e300\norigin = [1e-3, 1e-3]\n"),
     [], ["grid.spacing = 1e+300", "> 0.001 and <= 1000"]),
    ("particle-center-huge", scene(particles=particle(center="[1e300, 5.5e-3]")), [],
     ["particles[0].center = [1e+300, 0.0055]", "within +-1000"]),
    ("scene-file-missing", None, ["{TMP}/missing.toml"], ["scene file", "not found"]),
    ("scene-file-is-directory", None, ["{TMP}"], ["scene file", "is a directory"]),
]


@pytest.mark.parametrize("text,args,expected", [c[1:] for c in CLI], ids=[c[0] for c in CLI])
def test_cli_bad_input_one_line(tmp_path, capsys, text, args, expected):
    regular = tmp_path / "a_regular_file"
    regular.write_text("not a directory\n")

    def fill(s):
        return s.replace("{FILE}", str(regular)).replace("{TMP}", str(tmp_path))

    args = [fill(a) for a in args]
    if text is None:
        argv = ["run", *args]
    else:
        path = tmp_path / "bad.toml"
        path.write_text(fill(text))
        if args == ["NO-OUT"]:  # the scene's output.directory is under test
            args = []
        elif "--out" not in args:
            args = ["--out", str(tmp_path / "out"), *args]
        argv = ["run", str(path), *args]
    code = main([*argv, "--no-progress"])
    cap = capsys.readouterr()
    lines = cap.err.splitlines()
    assert code == 2, cap
    assert len(lines) == 1, lines
    assert lines[0].startswith("skfem-granular: error: ")
    for part in expected:
        assert fill(part) in lines[0]
    assert "Traceback" not in cap.err and cap.out == ""


# The other commands: (id, command line, expected substrings); {TMP} is an empty folder
# (not a run's), {FILE} a regular file in it, {RUN} a folder holding a simulation run's
# output. Refused before anything is read or written.
COMMANDS = [
    ("render-fps-tiny", ["render", "{TMP}", "--animation", "{TMP}/a.gif", "--fps", "1e-300"],
     ["--fps = 1e-300", "must be a finite number in [0.1, 100]"]),
    ("render-fps-zero", ["render", "{TMP}", "--animation", "{TMP}/a.gif", "--fps", "0"],
     ["--fps = 0.0", "must be a finite number in [0.1, 100]"]),
    ("render-fps-above-100", ["render", "{TMP}", "--animation", "{TMP}/a.gif", "--fps", "120"],
     ["--fps = 120.0", "must be a finite number in [0.1, 100]"]),
    ("render-fps-huge", ["render", "{TMP}", "--animation", "{TMP}/a.gif", "--fps", "1e300"],
     ["--fps = 1e+300", "must be a finite number in [0.1, 100]"]),
    ("render-fps-inf", ["render", "{TMP}", "--animation", "{TMP}/a.gif", "--fps", "inf"],
     ["--fps = inf", "must be a finite number in [0.1, 100]"]),
    ("render-fps-nan", ["render", "{TMP}", "--animation", "{TMP}/a.gif", "--fps", "nan"],
     ["--fps = nan", "must be a finite number in [0.1, 100]"]),
    ("render-every-zero", ["render", "{TMP}", "--animation", "{TMP}/a.gif", "--every", "0"],
     ["--every = 0", "must be an integer >= 1"]),
    ("render-png-suffix", ["render", "{TMP}", "--png", "{TMP}/a.jpg"],
     ["--png = '{TMP}/a.jpg'", "must end in .png"]),
    ("render-png-under-file", ["render", "{TMP}", "--png", "{FILE}/a.png"],
     ["--png = '{FILE}/a.png'", "must be a file that can be written", "is not a directory"]),
    ("render-png-is-directory", ["render", "{TMP}", "--png", "{TMP}/d.png"],
     ["--png = '{TMP}/d.png'", "must be a file that can be written", "is a directory"]),
    ("render-animation-suffix", ["render", "{TMP}", "--animation", "{TMP}/a.avi"],
     ["--animation = '{TMP}/a.avi'", "must end in .gif or .mp4"]),
    ("render-animation-under-file", ["render", "{TMP}", "--animation", "{FILE}/sub/a.gif"],
     ["--animation = '{FILE}/sub/a.gif'", "must be a file that can be written",
      "is not a directory"]),
    ("study-workers-zero", ["study", "faxen", "--out", "{TMP}/s", "--workers", "0"],
     ["--workers = 0", "must be an integer in [1, 1024]"]),
    ("study-workers-huge", ["study", "faxen", "--out", "{TMP}/s", "--workers", "100000"],
     ["--workers = 100000", "must be an integer in [1, 1024]"]),
    ("study-out-holds-a-run", ["study", "faxen", "--out", "{RUN}"],
     ["output folder '{RUN}'", "holds a simulation run's output (history.csv, summary.json)",
      "a study needs a folder of its own"]),
    ("study-out-holds-a-run-overwrite", ["study", "faxen", "--out", "{RUN}", "--overwrite"],
     ["output folder '{RUN}'", "holds a simulation run's output (history.csv, summary.json)",
      "a study needs a folder of its own"]),
    ("pack-n-zero", ["pack", "0", "--out", "{TMP}/p.npz"], ["n = 0", "integer in [1, 10000]"]),
    ("pack-n-huge", ["pack", "100000000", "--out", "{TMP}/p.npz"],
     ["n = 100000000", "integer in [1, 10000]"]),
    ("pack-aspect-nan", ["pack", "10", "--out", "{TMP}/p.npz", "--aspect", "nan"],
     ["--aspect = nan", "finite number in [0.05, 20]"]),
    ("pack-seed-negative", ["pack", "10", "--out", "{TMP}/p.npz", "--seed", "-1"],
     ["--seed = -1", "integer in [0, 4294967295]"]),
    ("pack-size-ratio-inf", ["pack", "10", "--out", "{TMP}/p.npz", "--size-ratio", "inf"],
     ["--size-ratio = inf", "finite number in [1, 4]"]),
    ("pack-d-mean-huge", ["pack", "10", "--out", "{TMP}/p.npz", "--d-mean", "1e300"],
     ["--d-mean = 1e+300", "finite number in [1e-05, 0.1]"]),
    ("pack-d-mean-negative", ["pack", "10", "--out", "{TMP}/p.npz", "--d-mean", "-1"],
     ["--d-mean = -1.0", "finite number in [1e-05, 0.1]"]),
    ("pack-margin-negative", ["pack", "10", "--out", "{TMP}/p.npz", "--margin", "-1"],
     ["--margin = -1.0", "finite number in [0, 20]"]),
    ("pack-out-under-file", ["pack", "10", "--out", "{FILE}/p.npz"],
     ["--out = '{FILE}/p.npz'", "must be a file that can be written", "is not a directory"]),
    ("pack-scene-under-file", ["pack", "10", "--out", "{TMP}/p.npz", "--scene", "{FILE}/s.toml"],
     ["--scene = '{FILE}/s.toml'", "must be a file that can be written", "is not a directory"]),
    ("collapse-n-one", ["collapse", "1", "--out", "{TMP}/c"], ["n = 1", "integer in [2, 10000]"]),
    ("collapse-n-huge", ["collapse", "100000000", "--out", "{TMP}/c"],
     ["n = 100000000", "integer in [2, 10000]"]),
    ("collapse-cores-zero", ["collapse", "10", "--out", "{TMP}/c", "--cores", "0"],
     ["--cores = 0.0", "finite number in (0, 1]"]),
    ("collapse-seeds-negative", ["collapse", "10", "--out", "{TMP}/c", "--seeds", "0", "-1"],
     ["--seeds = -1", "integer in [0, 4294967295]"]),
    ("collapse-aspect-huge", ["collapse", "10", "--out", "{TMP}/c", "--aspect", "1e300"],
     ["--aspect = 1e+300", "finite number in [0.05, 20]"]),
    ("collapse-tau-zero", ["collapse", "10", "--out", "{TMP}/c", "--tau", "0"],
     ["--tau = 0.0", "finite number in (0, 1000]"]),
    ("collapse-tau-huge", ["collapse", "10", "--out", "{TMP}/c", "--tau", "1e300"],
     ["--tau = 1e+300", "finite number in (0, 1000]"]),
    ("collapse-stop-ratio-one",
     ["collapse", "10", "--out", "{TMP}/c", "--to-rest", "--stop-ratio", "1"],
     ["--stop-ratio = 1.0", "finite number in (0, 1)"]),
    ("collapse-t-min-after-end", ["collapse", "10", "--out", "{TMP}/c", "--to-rest",
                                  "--tau", "10", "--t-min", "12"],
     ["--t-min = 12.0", "finite number in [0, 10)"]),
    ("collapse-checkpoint-every-zero",
     ["collapse", "10", "--out", "{TMP}/c", "--checkpoint-every", "0"],
     ["--checkpoint-every = 0", "integer >= 1"]),
    ("collapse-workers-huge", ["collapse", "10", "--out", "{TMP}/c", "--workers", "100000"],
     ["--workers = 100000", "integer in [1, 1024]"]),
]


@pytest.mark.parametrize("argv,expected", [c[1:] for c in COMMANDS], ids=[c[0] for c in COMMANDS])
def test_other_commands_bad_input_one_line(tmp_path, capsys, argv, expected):
    """Exit status 2, one line, nothing printed on stdout and nothing written."""
    regular = tmp_path / "a_regular_file"
    regular.write_text("not a directory\n")
    (tmp_path / "d.png").mkdir()
    run = tmp_path / "run"
    run.mkdir()
    (run / "history.csv").write_text("t,dt\n")
    (run / "summary.json").write_text("{}")

    def fill(s):
        return (s.replace("{FILE}", str(regular)).replace("{RUN}", str(run))
                .replace("{TMP}", str(tmp_path)))

    before = sorted(tmp_path.rglob("*"))
    code = main([fill(a) for a in argv])
    cap = capsys.readouterr()
    lines = cap.err.splitlines()
    assert code == 2, cap
    assert len(lines) == 1, lines
    assert lines[0].startswith("skfem-granular: error: ")
    for part in expected:
        assert fill(part) in lines[0], lines[0]
    assert "Traceback" not in cap.err and cap.out == ""
    assert sorted(tmp_path.rglob("*")) == before


# ---------------------------------------------------------------- library calls
DISK = Polygon.regular(24, 0.5e-3, center=(1.5e-3, 5.5e-3))
BOX = (0.0, 0.0, 3e-3, 11e-3)


def _base():
    return Scene(domain=BOX, particles=[ParticleSpec(DISK, 2650.0)], time=TimeSpec(2e-5, 1e-5))


def _unit_mesh():
    return meshing.uniform_mesh((0.0, 0.0, 1.0, 1.0), [], h=0.25)


def _dict(**sections):
    d = {"domain": {"box": list(BOX)}, "particles": [{"sides": 6, "radius": 0.5e-3,
                                                      "center": [1.5e-3, 5.5e-3],
                                                      "density": 2650.0}]}
    d.update(sections)
    return d


def _regular_file(tmp):
    f = tmp / "a_regular_file"
    f.write_text("x")
    return f


# (id, call(tmp_path), expected substrings)
LIB = [
    ("taylor-hood-array-not-mesh", lambda t: TaylorHood(np.zeros((2, 3))),
     ["mesh: a skfem.MeshTri is required", "ndarray"]),
    ("solve_steady-filename-not-mesh",
     lambda t: solve_steady("mesh.msh", Fluid(), {"wall": (0.0, 0.0)}),
     ["mesh: a skfem.MeshTri is required", "str"]),
    ("integrator-list-not-mesh", lambda t: BDF2Integrator([1, 2, 3], Fluid(), {}),
     ["mesh: a skfem.MeshTri is required"]),
    ("unknown-boundary-name", lambda t: solve_steady(_unit_mesh(), Fluid(), {"lid": (1.0, 0.0)}),
     ["velocity['lid']: no such boundary", "'wall'", "'top'"]),
    ("particle-boundary-on-empty-mesh",
     lambda t: BDF2Integrator(_unit_mesh(), Fluid(), {"particle0": (0.0, 0.0)}),
     ["velocity['particle0']: no such boundary"]),
    ("boundary-list-not-mapping", lambda t: solve_steady(_unit_mesh(), Fluid(), [(1.0, 0.0)]),
     ["velocity: must be a mapping"]),
    ("boundary-value-nan",
     lambda t: solve_steady(_unit_mesh(), Fluid(), {"top": (np.nan, 0.0)}),
     ["velocity['top']", "2 finite numbers"]),
    ("fluid-string", lambda t: solve_steady(_unit_mesh(), "water", {"wall": (0.0, 0.0)}),
     ["fluid: a skfem_granular.Fluid is required"]),
    ("evolve-end-before-start",
     lambda t: list(evolve(_unit_mesh(), Fluid(), {"wall": (0.0, 0.0)}, dt=0.1, t_end=-1.0)),
     ["t_end = -1.0", "> the initial time 0.0"]),
    ("evolve-t0-after-end",
     lambda t: list(evolve(_unit_mesh(), Fluid(), {"wall": (0.0, 0.0)}, dt=0.1, t_end=1.0,
                           t0=2.0)),
     ["t_end = 1.0", "> the initial time 2.0"]),
    ("evolve-dt-zero",
     lambda t: list(evolve(_unit_mesh(), Fluid(), {"wall": (0.0, 0.0)}, dt=0.0, t_end=1.0)),
     ["dt = 0.0", "> 0"]),
    ("fluid-density-nan", lambda t: Fluid(density=np.nan), ["Fluid.density = nan", "> 0"]),
    ("fluid-viscosity-bool", lambda t: Fluid(viscosity=True), ["Fluid.viscosity = True", "> 0"]),
    ("graded-clockwise", lambda t: meshing.graded_mesh(BOX, [DISK.vertices[:, ::-1]]),
     ["particles[0]: outline is clockwise", "counter-clockwise"]),
    ("graded-non-convex",
     lambda t: meshing.graded_mesh(BOX, [np.array([[1e-3, 2e-3, 1.5e-3, 2e-3, 1e-3],
                                                   [5e-3, 5e-3, 5.5e-3, 6e-3, 6e-3]])]),
     ["particles[0]: outline is not convex"]),
    ("graded-overlap",
     lambda t: meshing.graded_mesh(BOX, [DISK.vertices, DISK.vertices + 2e-4]),
     ["particles[0] and particles[1] overlap", "disjoint"]),
    ("graded-outside", lambda t: meshing.graded_mesh(BOX, [DISK.vertices + 5e-3]),
     ["particles[0]", "inside the domain"]),
    ("uniform-h-zero", lambda t: meshing.uniform_mesh((0.0, 0.0, 1.0, 1.0), [], h=0.0),
     ["h: must be in (0, 0.5]"]),
    ("polygon-clockwise", lambda t: Polygon([[0, 0, 1, 1], [0, 1, 1, 0]], name="p"),
     ["p has signed area -1", "must be > 0"]),
    ("dem-overlap",
     lambda t: DEMSystem([Particle(DISK, 2650.0), Particle(DISK, 2650.0)]),
     ["particles[0] and particles[1] overlap", "overlap_tolerance"]),
    ("dem-dt-negative", lambda t: DEMSystem([Particle(DISK, 2650.0)], dt=-1.0),
     ["dt = -1.0", "> 0"]),
    ("timespec-end-before-start", lambda t: TimeSpec(t_end=-1.0), ["time.t_end = -1.0", "> 0"]),
    ("timespec-bool", lambda t: TimeSpec(t_end=True), ["time.t_end = True", "> 0"]),
    ("meshspec-sigma-inf", lambda t: MeshSpec(sigma=np.inf), ["mesh.sigma = inf", "<= 1.6"]),
    ("meshspec-wake-string", lambda t: MeshSpec(wake="yes"),
     ["mesh.wake = 'yes'", "true or false"]),
    ("effects-int", lambda t: Effects(gravity=1), ["effects.gravity = 1", "true or false"]),
    ("scene-fluid-string", lambda t: replace(_base(), fluid="water"),
     ["scene.fluid = 'water'", "must be a Fluid or None"]),
    ("scene-mesh-string", lambda t: replace(_base(), mesh="graded"),
     ["scene.mesh = 'graded'", "must be a MeshSpec"]),
    ("scene-time-tuple", lambda t: replace(_base(), time=(1e-3, 1e-5)),
     ["scene.time = (0.001, 1e-05)", "must be a TimeSpec"]),
    ("scene-contact-law-dict", lambda t: replace(_base(), contact_law={"E": 1e7}),
     ["scene.contact_law", "must be a ContactLaw"]),
    ("particle-polygon-array",
     lambda t: Scene(domain=BOX, particles=[ParticleSpec(DISK.vertices, 2650.0)]),
     ["particles[0].polygon: must be a Polygon"]),
    ("scene-output-dir-int", lambda t: replace(_base(), output_dir=5),
     ["output.directory = 5", "directory path"]),
    ("scene-vtu_every-bool", lambda t: replace(_base(), vtu_every=True),
     ["output.vtu_every = True", "integer >= 0"]),
    ("simulation-output-under-file",
     lambda t: Simulation(_base(), output_dir=_regular_file(t) / "out"),
     ["output path", "cannot create directory (Not a directory)"]),
    ("simulation-output-is-file", lambda t: Simulation(_base(), output_dir=_regular_file(t)),
     ["output path", "is not a directory"]),
    ("simulation-toml-is-directory", lambda t: Simulation(str(t)),
     ["scene file", "is a directory"]),
    ("from_dict-not-a-dict", lambda t: Scene.from_dict(None),
     ["scene = None", "must be a table of sections"]),
    ("from_dict-section-int", lambda t: Scene.from_dict(_dict(fluid=5)),
     ["fluid = 5", "must be a table"]),
    ("from_dict-particle-int", lambda t: Scene.from_dict(_dict(particles=[1])),
     ["particles[0] = 1", "must be a table"]),
    ("from_dict-nx-bool",
     lambda t: Scene.from_dict(_dict(grid={"nx": True, "ny": 1, "radius": 0.1e-3,
                                           "origin": [1e-3, 1e-3]})),
     ["grid.nx = True", "integer in [1, 100]"]),
    ("from_dict-contacts-mu-bool", lambda t: Scene.from_dict(_dict(contacts={"mu": True})),
     ["contacts.mu = True", ">= 0"]),
    ("contact-law-string", lambda t: ContactLaw(E="stiff"), ["ContactLaw.E = 'stiff'", "> 0"]),
    ("contact-law-bool", lambda t: ContactLaw(mu=True), ["ContactLaw.mu = True", ">= 0"]),
    ("polygon-overflow", lambda t: Polygon.regular(6, 1e200), ["radius", "< 1e+60"]),
    ("core-far-below-mesh-resolution",
     lambda t: Simulation(Scene.from_dict(_dict(
         fluid={"density": 1000.0, "viscosity": 1e-3},
         particles=[{"sides": 24, "radius": 0.5e-3, "center": [1.5e-3, 5.5e-3],
                     "density": 2650.0, "core_ratio": 1e-5}],
         mesh={"kind": "graded"}))),
     ["particles[0]: extent", "below 1e-05 x the domain size"]),
    ("collapse-run-state", lambda t: CollapseRun(30, "medium", "dry"),
     ["state = 'medium'", "dense, loose"]),
    ("collapse-run-dry-core-ratio", lambda t: CollapseRun(30, "dense", "dry", core_ratio=0.8),
     ["core_ratio = 0.8", "a dry run has no fluid outline"]),
    ("collapse-study-workers", lambda t: run_collapse_study([], t, workers=0),
     ["workers = 0", "integer >= 1"]),
]


# ---------------------------------------------------------------- crafted checkpoints
_VALID_CHECKPOINT = {}


def _valid_checkpoint(tmp):
    """Header and arrays of a real checkpoint (the single particle after 2 steps; made once)."""
    from skfem_granular.io import plain

    if not _VALID_CHECKPOINT:
        sc = replace(Scene.bundled("single_particle"), time=TimeSpec(2e-5, 1e-5),
                     checkpoint_every=2)
        Simulation(sc, output_dir=tmp / "valid").run(progress=False)
        _VALID_CHECKPOINT["data"] = plain.read(tmp / "valid" / "checkpoint.npz")
        _VALID_CHECKPOINT["history"] = (tmp / "valid" / "history.csv").read_text()
    header, arrays = _VALID_CHECKPOINT["data"]
    import copy

    return copy.deepcopy(header), {k: v.copy() for k, v in arrays.items()}


def _node(header, path):
    """The header node of a field path (``stepper.state.u_n``)."""
    node = header["content"]
    for part in path.split(".") if path else []:
        if "$dict" in node:
            node = node["$dict"][part]
        elif "$object" in node:
            node = node["fields"][part]
        else:
            node = node["$tuple"][int(part)]
    return node


def _crafted(tmp, mutate, raw=None, **special):
    """Resume from a valid checkpoint changed by ``mutate(header, arrays)`` (next to the
    history file it follows); ``special``: :func:`_special_file` (a zip bomb, a huge
    declared shape, a deep header)."""
    import json
    import zipfile

    from skfem_granular.io import plain

    header, arrays = _valid_checkpoint(tmp)
    mutate(header, arrays)
    d = tmp / "crafted"
    d.mkdir(exist_ok=True)
    (d / "history.csv").write_text(_VALID_CHECKPOINT["history"])  # the rows it follows
    if special:
        _special_file(d / "checkpoint.npz", header, arrays, **special)
    elif raw is None:
        plain.write(d / "checkpoint.npz", header, arrays)
    else:  # members written as given (plain.write would refuse them)
        with zipfile.ZipFile(d / "checkpoint.npz", "w") as zf:
            zf.writestr("header.json", json.dumps(header))
            for k, v in arrays.items():
                with zf.open(f"{k}.npy", "w") as f:
                    np.lib.format.write_array(f, v, allow_pickle=False)
            for name, blob in raw.items():
                zf.writestr(name, blob)
    return Simulation.resume(d)


def _history(tmp, change):
    """Resume from the valid checkpoint next to its ``history.csv`` changed by
    ``change(lines)`` (the lines with their ends; ``None``: no history file)."""
    from skfem_granular.io import plain

    header, arrays = _valid_checkpoint(tmp)
    d = tmp / "history-case"
    d.mkdir(exist_ok=True)
    plain.write(d / "checkpoint.npz", header, arrays)
    lines = change(_VALID_CHECKPOINT["history"].splitlines(keepends=True))
    if lines is not None:
        (d / "history.csv").write_text("".join(lines))
    return Simulation.resume(d)


def _digit(row, column):
    """The lines with the last digit of ``column`` (0: t) in data row ``row`` changed."""
    def change(lines):
        vals = lines[row].rstrip("\n").split(",")
        v = vals[column]
        i = max(j for j, ch in enumerate(v) if ch.isdigit() and (j == 0 or v[j - 1] != "e"))
        vals[column] = v[:i] + str((int(v[i]) + 1) % 10) + v[i + 1:]
        return lines[:row] + [",".join(vals) + "\n"] + lines[row + 1:]
    return change


def _nested(depth):
    node = 0
    for _ in range(depth):
        node = [node]
    return node


def _coincide(h, a):
    """Two vertices of the first triangle at one point."""
    p, t = a["stepper.mesh.mesh.doflocs"].copy(), a["stepper.mesh.mesh.t"]
    p[:, t[1, 0]] = p[:, t[0, 0]]
    a["stepper.mesh.mesh.doflocs"] = p


def _special_file(path, header, arrays, bomb=0, huge=None, deep=0):
    """A checkpoint whose ``stepper.state.u_n`` member is a zip bomb (``bomb`` bytes of zeros,
    deflated to a few hundred kB) or declares the shape ``huge`` (header and ``.npy`` alike,
    the data absent), or whose header is ``deep`` lists deep (as text: JSON cannot write it)."""
    import json
    import zipfile

    key = "stepper.state.u_n"
    n = bomb // 8 if bomb else huge[0] if huge else None
    if n is not None:
        _node(header, key)["shape"] = [n]
    text = json.dumps(header)
    if deep:
        text = text[:-1] + ', "deep": ' + "[" * deep + "]" * deep + "}"
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("header.json", text)
        for k, v in arrays.items():
            if k != key or n is None:
                with zf.open(f"{k}.npy", "w") as f:
                    np.lib.format.write_array(f, v, allow_pickle=False)
                continue
            info = zipfile.ZipInfo(f"{k}.npy")
            info.compress_type = zipfile.ZIP_DEFLATED if bomb else zipfile.ZIP_STORED
            with zf.open(info, "w", force_zip64=True) as f:
                np.lib.format.write_array_header_1_0(
                    f, {"descr": "<f8", "fortran_order": False, "shape": (n,)})
                for _ in range(bomb // 2**24):
                    f.write(bytes(2**24))
                f.write(bytes(bomb % 2**24))


def _set(path, value):
    def mutate(h, a):
        parent, key = path.rsplit(".", 1) if "." in path else ("", path)
        node = _node(h, parent)
        (node["$dict"] if "$dict" in node else node["fields"])[key] = value
    return mutate


def _array(key, change):
    def mutate(h, a):
        a[key] = change(a[key])
    return mutate


def _both(path, change):
    """Array and header changed alike (the file is consistent, the values are not)."""
    def mutate(h, a):
        node = _node(h, path)
        a[node["$array"]] = change(a[node["$array"]])
        node["shape"] = list(a[node["$array"]].shape)
    return mutate


def _nan_at(i):
    def change(x):
        x = x.copy()
        x.flat[i] = np.nan
        return x
    return change


def _object_npy():
    import io

    buf = io.BytesIO()
    np.lib.format.write_array(buf, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    return buf.getvalue()


def _pop_field(path):
    def mutate(h, a):
        parent, key = path.rsplit(".", 1)
        node = _node(h, parent)
        arr = node["fields"].pop(key)
        a.pop(arr["$array"], None) if isinstance(arr, dict) and "$array" in arr else None
    return mutate


def _extra(h, a):
    h["content"]["$dict"]["evil"] = 1


CHECKPOINTS = [
    ("checkpoint-array-shape-vs-header",
     lambda t: _crafted(t, _array("stepper.state.u_n", lambda x: x[:-1])),
     ["stepper.state.u_n: array of shape (1467,) in the file, (1468,) in the header"]),
    ("checkpoint-shape-vs-mesh",
     lambda t: _crafted(t, _both("stepper.state.u_n", lambda x: x[:-1])),
     ["stepper.state.u_n: shape (1467,): must be (1468,)"]),
    ("checkpoint-particle-shape",
     lambda t: _crafted(t, _both("dem.q", lambda x: np.zeros((3, 2)))),
     ["dem.q: shape (3, 2): must be (3, 1)"]),
    ("checkpoint-nan-fluid",
     lambda t: _crafted(t, _array("stepper.state.u_prev", _nan_at(5))),
     ["stepper.state.u_prev: contains NaN or inf", "must be finite"]),
    ("checkpoint-nan-dem", lambda t: _crafted(t, _array("dem.v", _nan_at(1))),
     ["dem.v: contains NaN or inf"]),
    ("checkpoint-nan-scalar",
     lambda t: _crafted(t, _set("stepper.state.dt_prev", {"$float": "nan"})),
     ["stepper.state.dt_prev: = nan: must be a finite number"]),
    ("checkpoint-float-tag-not-a-string",
     lambda t: _crafted(t, _set("stepper.state.dt_prev", {"$float": ["nan"]})),
     ["stepper.state.dt_prev: $float = ['nan']: must be 'nan', 'inf' or '-inf'"]),
    ("checkpoint-numpy-tag-not-a-string",
     lambda t: _crafted(t, _set("stepper.state.dt_prev", {"$numpy": {}, "value": 1.0})),
     ["stepper.state.dt_prev: numpy scalar type {}: must be one of float64"]),
    ("checkpoint-array-dtype-not-a-string",
     lambda t: _crafted(t, lambda h, a: _node(h, "stepper.state.u_n").update(dtype=["f8"])),
     ["stepper.state.u_n: dtype ['f8']: must be one of float64, int64, bool, int32"]),
    ("checkpoint-unknown-version", lambda t: _crafted(t, lambda h, a: h.update(version=99)),
     ["version = 99", "reads checkpoint versions 3 and 4 only"]),
    ("checkpoint-other-format",
     lambda t: _crafted(t, lambda h, a: h.update(format="something else")),
     ["format = 'something else'", "not a 'skfem-granular checkpoint' file"]),
    ("checkpoint-extra-header-key",
     lambda t: _crafted(t, lambda h, a: h.update(run="import os")),
     ["header: unknown key 'run'"]),
    ("checkpoint-extra-content-key", lambda t: _crafted(t, _extra),
     ["evil: unknown key", "a checkpoint holds"]),
    ("checkpoint-extra-field", lambda t: _crafted(t, _set("stepper.state.zzz", 1)),
     ["stepper.state.zzz: unknown field of skfem_granular.coupled.state.CoupledState"]),
    ("checkpoint-missing-field", lambda t: _crafted(t, _pop_field("stepper.state.u_prev")),
     ["stepper.state.u_prev: missing field"]),
    ("checkpoint-extra-stepper-entry",
     lambda t: _crafted(t, _set("stepper.evil", 1)),
     ["stepper.evil: unknown key (this version does not have it)"]),
    ("checkpoint-extra-array",
     lambda t: _crafted(t, lambda h, a: a.update(evil=np.zeros(3))),
     ["evil: array in the file that the header does not name"]),
    ("checkpoint-unknown-type",
     lambda t: _crafted(t, lambda h, a: _node(h, "stepper.state").update({"$object": "os.system"})),
     ["stepper.state: type 'os.system' is not one this file may hold"]),
    ("checkpoint-object-array",
     lambda t: _crafted(t, lambda h, a: None, raw={"evil.npy": _object_npy()}),
     ["evil: not a plain array", "allow_pickle=False"]),
    ("checkpoint-float32-array",
     lambda t: _crafted(t, _array("dem.v", lambda x: x.astype(np.float32)), raw={}),
     ["dem.v: array of dtype float32: must be one of float64, int64, int32, bool"]),
    ("checkpoint-bad-scene-value",
     lambda t: _crafted(t, _set("scene.particles.0.density", -1.0)),
     ["scene: particles[0].density = -1.0", "> 0"]),
    ("checkpoint-mesh-index",
     lambda t: _crafted(t, _array("stepper.mesh.mesh.t", lambda x: x + 10**6)),
     ["stepper.mesh.mesh: t: vertex indices must be in [0, 198)"]),
    ("checkpoint-frame-path",
     lambda t: _crafted(t, _set("frames.flow", [{"$tuple": [0.0, "../../etc/x.vtu"]}])),
     ["frames.flow[0]", "must be (t, 'flow_NNNNN.vtu')"]),
    ("checkpoint-history-rows",
     lambda t: _crafted(t, _set("k", 5)), ["k: = 5: must equal the number of history rows (2)"]),
    ("checkpoint-history-file-missing", lambda t: _history(t, lambda lines: None),
     ["history-case/history.csv'", "not found", "keeps its 2 rows there"]),
    ("checkpoint-history-file-shorter", lambda t: _history(t, lambda lines: lines[:2]),
     ["history.csv'", "1 complete rows, fewer than the 2", "the file was cut short"]),
    ("checkpoint-history-file-changed", lambda t: _history(t, _digit(1, 9)),
     ["history.csv'", "the bytes of its header and row 1 are not the ones checkpoint",
      "the file was changed"]),
    ("checkpoint-history-file-last-row", lambda t: _history(t, _digit(2, 9)),
     ["history.csv'", "row 2 is not the last row checkpoint", "values other than t differ"]),
    ("checkpoint-history-file-header",
     lambda t: _history(t, lambda lines: [lines[0].replace("x_0", "x_9")] + lines[1:]),
     ["history.csv'", "its header line is not the one of checkpoint", "K = 1 particles"]),
    ("checkpoint-zip-bomb", lambda t: _crafted(t, lambda h, a: None, bomb=400_000_000),
     ["stepper.state.u_n: compressed member (400000128 bytes inflated)",
      "arrays must be stored uncompressed"]),
    ("checkpoint-declared-shape-huge",
     lambda t: _crafted(t, lambda h, a: None, huge=(10**9,)),
     ["stepper.state.u_n: member of", "shape (1000000000,) takes 8000000128"]),
    ("checkpoint-nested-500-deep",
     lambda t: _crafted(t, _set("stepper.deep", _nested(500))),
     ["header.json: nested deeper than 64 levels"]),
    ("checkpoint-nested-100000-deep", lambda t: _crafted(t, lambda h, a: None, deep=100_000),
     ["header.json: nested deeper than 64 levels"]),
    ("checkpoint-mesh-vertices-coincide", lambda t: _crafted(t, _coincide),
     ["stepper.mesh.mesh: t: triangle 0 has no area (its vertices coincide"]),
    ("checkpoint-mesh-one-point",
     lambda t: _crafted(t, _array("stepper.mesh.mesh.doflocs", np.zeros_like)),
     ["stepper.mesh.mesh: t: triangle 0 has no area", "338 such triangles"]),
    ("checkpoint-not-a-zip",
     lambda t: ((t / "nz").mkdir(), (t / "nz" / "checkpoint.npz").write_text("PK?"),
                Simulation.resume(t / "nz")),
     ["not a readable file of this format"]),
]
LIB += CHECKPOINTS


def test_cli_resume_crafted_checkpoint_one_line(tmp_path, capsys):
    with pytest.raises(ValueError):
        _crafted(tmp_path, _array("stepper.state.u_prev", _nan_at(0)))
    code = main(["run", "--resume", str(tmp_path / "crafted"), "--no-progress"])
    lines = capsys.readouterr().err.splitlines()
    assert code == 2 and len(lines) == 1, lines
    assert "stepper.state.u_prev: contains NaN or inf" in lines[0]


def _param(row):
    if hasattr(row, "marks"):  # already a pytest.param (an xfail row)
        return pytest.param(*row.values[1:], marks=row.marks, id=row.id)
    return pytest.param(*row[1:], id=row[0])


@pytest.mark.parametrize("call,expected", [_param(r) for r in LIB])
def test_library_bad_input_value_error(tmp_path, call, expected):
    with pytest.raises(ValueError) as info:
        call(tmp_path)
    msg = str(info.value)
    assert "\n" not in msg.strip(), msg
    for part in expected:
        assert part in msg, msg
    # raised by project code, not from deep inside numpy / scipy / triangle
    origin = str(info.traceback[-1].path)
    assert origin.startswith(PROJECT_DIRS), origin


def test_tables_are_big_enough():
    assert len(CLI) + len(LIB) >= 25


@pytest.mark.parametrize("row", ["checkpoint-zip-bomb", "checkpoint-declared-shape-huge",
                                 "checkpoint-nested-500-deep", "checkpoint-nested-100000-deep",
                                 "checkpoint-mesh-one-point"])
def test_crafted_checkpoint_is_refused_before_its_data_is_inflated(tmp_path, monkeypatch, row):
    """The refusal reads at most 1 MB out of the archive's members (before: the 1.6 MB
    bomb was inflated to 1.6 GB first, then refused); counted as the bytes the zip members
    hand out, not as a memory figure of the process. Measured: 7.9-208 kB (a good
    checkpoint of the paper's particle: 63 kB)."""
    import zipfile

    call, expected = next(c[1:] for c in CHECKPOINTS if c[0] == row)
    with pytest.raises(ValueError):
        call(tmp_path)  # writes tmp_path / "crafted" / "checkpoint.npz"
    handed_out = []
    read = zipfile.ZipExtFile.read

    def counted(self, n=-1):
        data = read(self, n)
        handed_out.append(len(data))
        return data

    monkeypatch.setattr(zipfile.ZipExtFile, "read", counted)
    with pytest.raises(ValueError, match=re.escape(expected[0])):
        Simulation.resume(tmp_path / "crafted")
    assert sum(handed_out) < 1_000_000, f"{row}: {sum(handed_out)} bytes read"


# ---------------------------------------------------------------- the docs' table
DOC_PAGE = ROOT / "docs" / "bad_input.md"
DOC_HEAD = """\
# Bad input: every refusal

Generated from the rows of `tests/test_bad_input.py` by
`python scripts/bad_input_table.py` (a test checks that this page is up to
date). Every row is a test: the command line (a scene with one changed value,
or the options shown) must stop with exit status 2 and exactly one line on
stderr that contains the parts listed, before any work and without a
traceback; a library call must raise a `ValueError` of one line, from this
package's code. Folder, signal and write failures are tested in
`tests/test_output_folder.py` ({ref}`the output folder <output-folder>`).
"""


def _cell(text) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _what(text, args) -> str:
    """The scene lines a row changes (against the valid scene) and its options."""
    if text is None:
        return "`run " + " ".join(args) + "`"
    base = set(scene().splitlines())
    changed = [ln for ln in text.splitlines() if ln and ln not in base]
    parts = [f"`{ln}`" for ln in changed[:4]] + (["..."] if len(changed) > 4 else [])
    opts = " ".join(a for a in args if a != "NO-OUT")
    return " ".join(parts + ([f"`{opts}`"] if opts else [])) or "(see the test)"


def table_markdown() -> str:
    """The docs page: tables of the command line's rows (run, the other commands) and one of
    the library's."""
    lines = [DOC_HEAD, "## Command line (exit status 2)", "",
             "| case | given | the one line contains |", "|---|---|---|"]
    for case, text, args, expected in CLI:
        parts = "; ".join(f"`{_cell(e)}`" for e in expected)
        lines.append(f"| {case} | {_cell(_what(text, args))} | {parts} |")
    lines += ["", "## Other commands (exit status 2)", "",
              "Refused before anything is read or written (`{TMP}`: a folder, `{FILE}`: a "
              "regular file, `{RUN}`: a folder holding a simulation run's output).", "",
              "| case | command | the one line contains |", "|---|---|---|"]
    for case, argv, expected in COMMANDS:
        parts = "; ".join(f"`{_cell(e)}`" for e in expected)
        lines.append(f"| {case} | `{_cell(' '.join(argv))}` | {parts} |")
    lines += ["", "## Library calls and checkpoints (`ValueError`)", "",
              "| case | the message contains |", "|---|---|"]
    for row in LIB:
        case, expected = (row.id, row.values[2]) if hasattr(row, "values") else (row[0], row[2])
        parts = "; ".join(f"`{_cell(e)}`" for e in expected)
        lines.append(f"| {case} | {parts} |")
    return "\n".join(lines) + "\n"


def test_docs_table_is_generated_from_these_rows():
    assert DOC_PAGE.read_text() == table_markdown(), \
        "docs/bad_input.md is out of date: run python scripts/bad_input_table.py"
