"""The multiscale solver against YADE's FEMxDEM on the same scaled biaxial (2D) and
triaxial (3D) problems.

FEMxDEM (Guo & Zhao's FEM x DEM coupling: Escript's finite elements with a YADE
periodic RVE at every Gauss point, the ``yade.FEMxDEM`` module of Debian's yade
package, with its ``msFEM2D.MultiScale`` Newton solver and ``simDEM`` RVE calls) is
the ancestor of ``hmm``. Both solve the same problem here:

* a 2D plane-strain sample of 5 x 10 cm (the sample of FEMxDEM's biaxial example),
  8-node serendipity quadrilaterals with 2 x 2 Gauss points (Escript's
  ``Rectangle(order=2, integrationOrder=2)``, our ``quad8``), meshes of 2 x 4
  (32 Gauss points) and 4 x 8 elements (128);
* smooth platens: bottom ``u_y = 0``, top ``u_y`` prescribed in load steps of 1e-3
  axial strain (50 on the 2 x 4 mesh, to 5 %, past the peak; 10 on the 4 x 8 mesh,
  to 1 %), a lateral confining pressure of 100 kPa;
* every Gauss point starts from the same 400-disk periodic packing, consolidated to
  100 kPa: the packing of ``benchmarks/rve_vs_yade.py`` (radii 0.8-1.2 mm,
  kn = 1e8 N/m, kt = 5e7 N/m, friction 0.5, density 2650 kg/m^3, Cundall local
  damping 0.5, its time step), exported with that benchmark's helpers. Each engine
  starts from the exported positions with fresh contacts and consolidates once more
  to 100 kPa with the algorithm of ``RVE.consolidate`` (YADE through the script of
  ``rve_vs_yade.py``); ours is saved with ``RVE.save`` and read through ``[micro]
  packing``, YADE's scene with ``O.save`` as the ``0.yade.gz`` that FEMxDEM's
  ``simDEM.initLoad`` loads at every Gauss point. The contact law is matched as in
  ``rve_vs_yade.py``: one ``FrictMat`` per particle with ``young = kn / r``,
  ``poisson = kt / kn``, ``frictionAngle = atan(mu)``; 2D disks are YADE spheres in
  one plane of a periodic cell with ``blockedDOFs = "zXY"`` and our disks' masses
  and moments of inertia.

``DIM=3`` runs the 3D part, the scaled triaxial test of FEMxDEM's
``triaxialRough.py`` example (``msFEM3D.MultiScale``, ``simDEM.shear3D``):

* a 5 x 10 x 5 cm cuboid, its axis along y (FEMxDEM's example runs along z; the
  driver here turns it), 20-node hexahedra with 2 x 2 x 2 Gauss points (Escript's
  ``Brick(order=2, integrationOrder=2)``, our ``hex20`` with ``integration =
  "reduced"``), 1 x 1 x 2 elements (16 Gauss points) by default;
* rough platens as in the example: the bottom held in every component, the top
  held in x and z with ``u_y`` prescribed in load steps of 1e-3 axial strain; the
  100 kPa confining pressure on the four sides;
* every Gauss point starts from the 1,000-sphere packing of ``rve_vs_yade.py``
  (kn = 1e5 N/m, kt = 5e4 N/m, friction 0.5), consolidated to 100 kPa by each engine
  as in 2D.

The shipped ``msFEM3D`` calls ``shear``, ``getStressAndTangent``, ``getVoidRatio``,
``avgRotation`` and ``getFabric``, which its ``simDEM`` names with a ``3D`` suffix
(``shear3D`` ...); the driver binds those names in ``msFEM3D`` and changes nothing
else. Its results go to ``benchmarks/results/hmm_vs_femxdem_3d.json`` and
``docs/figures/hmm_vs_femxdem_3d.png``, with the same keys.

Ours is ``hmm.run.run_problem`` on a validated problem (micro model ``dem``); the
peer is a driver script this file writes (:data:`FEMXDEM_DRIVER`, our own text) that
builds the Escript domain and the boundary conditions and calls
``MultiScale.solve`` step by step. Both run on 1 process and on 2 (ours under the
venv's ``mpiexec -n 2`` with one numba thread per rank; FEMxDEM with its
``multiprocessing`` pool of 2 workers).

Measured per mesh and process count: wall time per load step (the solve, set-up
excluded), wall time of the micro stage per Gauss-point call (all Gauss points of a
Newton iteration, transfers included, divided by their number), Gauss-point
evaluations per step, DEM steps per call, and the volume-averaged macro stress after
every step. ``speedup`` = FEMxDEM's wall per load step / ours, same processes;
``max_rel_stress_deviation`` = the largest difference of the mean axial stress
sigma_yy over the run relative to its largest magnitude (ours); the deviator
sigma_xx - sigma_yy is compared the same way (``max_rel_deviator_deviation``), a
stricter number since sigma_yy carries the 100 kPa of confinement. Ours runs a second
time with FEMxDEM's RVE call (no relaxation, see below): the keys ending in
``_no_relaxation`` compare that run, the engines on the same algorithm;
``max_rel_stress_deviation_relaxation`` compares our two runs, the measure of what
relaxing every call changes (the rate effect of an unrelaxed call: its stress is
that of a packing still moving at the loading rate).

Where the two set-ups cannot be made identical:

* **Relaxation.** FEMxDEM's ``shear2D`` runs a fixed ``max(1e5 max|grad du|, 2)``
  steps per call (at most 1e-5 strain per step, as our ``max_step_strain``) and
  returns the unrelaxed state: it exposes no relaxation tolerance. Ours relaxes
  every call to an unbalanced-force ratio of 1e-3 after the same loading steps. The
  DEM steps per call are reported for both.
* **Newton.** FEMxDEM stops when ``L2(du) / L2(u) < rtol`` (u: the step's
  displacement; ``rtol`` = 1e-2 as in its example), with no residual check and no
  step cutting; ours runs with ``check_residual = false``, which converges on the
  same criterion (or on a residual below ``tol_residual``, both 1e-2), and cuts
  steps that fail: past the peak the residual of 400-disk RVEs sits above any
  useful tolerance, for both engines.
  FEMxDEM's Gauss-point evaluations per step are its iterations + 1, ours equal its
  iterations.
* **Kinematics.** Both are updated Lagrangian: FEMxDEM moves its mesh with ``setX``
  after each iteration and step and hands each RVE the displacement gradient of the
  step on the last converged configuration as its velocity gradient; ours runs
  ``[solver] kinematics = "finite"``, which does the same (the RVE's cell turns
  with the material, the Newton matrix has the geometric stiffness). FEMxDEM's
  ``shear2D`` applies ``grad du / (n dt)`` for ``n`` steps, whose map is
  ``I + grad du`` to first order; ours applies its exact matrix root.
* **The lateral support.** FEMxDEM's example pins the bottom centre node and puts the
  pressure on both sides; ``hmm``'s problems name supports by boundary, so both
  engines here hold ``u_x = 0`` on the left side (a symmetry plane) with the
  pressure on the right: the same problem for a homogeneous sample.
* **The RVE state.** Each engine re-consolidates the exported packing itself (fresh
  contacts), so the two start within the consolidation tolerance (1e-3 of 100 kPa),
  not bit for bit (measured: their stresses agree to within 1 Pa). YADE's cell is 1 m thick, so that its stress per volume is ours
  per area (a thin cell as in ``rve_vs_yade.py`` would need YADE's stress rescaled
  inside FEMxDEM's own calls).
* **Transfers.** FEMxDEM pickles every RVE scene to a string and back at every
  call (its ``sceneToString``/``stringToScene``), with one process (mapped here in
  process, since its pool refuses a single process) as with two; ours keeps the
  RVEs in place and moves float64 buffers. That is part of what is measured.

usage::

    python benchmarks/hmm_vs_femxdem.py   # writes benchmarks/results/hmm_vs_femxdem.json
                                          # and docs/figures/hmm_vs_femxdem.png

environment: DIM ("2"; "3": the triaxial part), SIZES ("2x4:50 4x8:10" in 2D,
"1x1x2:40" in 3D: mesh and load steps; a size without steps takes STEPS, 3),
PEER_STEPS (the same; fewer keep a slow peer within the time budget: the ratios are
per step and per call), PROCS ("2"), KINEMATICS ("finite", ours), YADE (the YADE
executable, default ``yade``; FEMxDEM runs under the Python of its launch script); PUBLISHED ("8x16:100" runs ours alone on the
published problem size, FEMxDEM's RVE call then relaxed (PUBLISHED_RUNS, "fixed
relax"), on PUBLISHED_PROCS (2) processes, and adds it to the JSON). Without YADE or
Escript the peer is skipped,
saying so on stdout and in the JSON, and our side still runs.
"""

import json
import math
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C
import rve_vs_yade as RV

DIM = int(os.environ.get("DIM", "2"))
if DIM not in (2, 3):
    raise SystemExit(f"DIM must be 2 or 3, not {DIM}")
_TAG = "" if DIM == 2 else "_3d"
OUT = C.RESULTS / f"hmm_vs_femxdem{_TAG}.json"
FIGURE = C.REPO / "docs" / "figures" / f"hmm_vs_femxdem{_TAG}.png"
SCRATCH = C.WORK / "hmm_vs_femxdem"
PACKING = SCRATCH / f"packing_{DIM}d.h5"  # ours, consolidated (RVE.save)
EXPORT = SCRATCH / f"export_{DIM}d.json"  # the exported packing, for YADE
PEER_DIR = SCRATCH / f"femxdem_{DIM}d"  # FEMxDEM's working directory (0.yade.gz, ...)

P0 = RV.P0  # [Pa] consolidation and confining pressure
#: [m] the samples of FEMxDEM's biaxial example (2D) and of its triaxial example (3D,
#: its axis along y here as in examples/triaxial_3d.toml; FEMxDEM's runs along z)
SIZE = (0.05, 0.1) if DIM == 2 else (0.05, 0.1, 0.05)
ELEMENT = "quad8" if DIM == 2 else "hex20"
#: meshes and load steps run by default
DEFAULT_SIZES = "2x4:50 4x8:10" if DIM == 2 else "1x1x2:40"
STRAIN_STEP = 1e-3  # axial strain per load step
YADE_THICKNESS = 1.0  # [m] YADE's cell: stress per (area x 1 m) = ours per area
RTOL = 1e-2  # FEMxDEM's Newton tolerance (its example's); ours both tolerances
ITER_MAX = 20  # FEMxDEM's iteration cap per step
#: our RVE and solver settings (the RVE settings of benchmarks/rve_vs_yade.py)
MICRO = {"damping": RV.TEST["damping"], "tol": RV.TEST["tol"],
         "max_step_strain": RV.TEST["max_step_strain"],
         "max_relax_steps": RV.TEST["max_relax_steps"]}
SOLVER = {"tol_residual": RTOL, "tol_displacement": RTOL, "max_iterations": 20,
          "check_residual": False}
KINEMATICS = os.environ.get("KINEMATICS", "finite")


# --------------------------------------------------------------------------- our side
def prepare_ours():
    """The packing of rve_vs_yade.py, re-consolidated from fresh contacts and saved
    for ``[micro] packing``; its export for YADE (made once, then read from the
    scratch directory). Runs in a worker (numba)."""
    from dem import rve

    if PACKING.exists() and EXPORT.exists():
        r = rve.RVE.load_file(PACKING)
    else:
        ex = RV.export(DIM)  # positions etc. of the packing at the working friction
        r = RV.fresh_rve(ex)
        r.consolidate(P0)
        SCRATCH.mkdir(parents=True, exist_ok=True)
        r.save(PACKING, p0=P0)
        EXPORT.write_text(json.dumps(dict(ex, thickness=YADE_THICKNESS)))
    res = r.response(tangent=False)
    return {"stress": res["stress"].tolist(), "n_contacts": res["n_contacts"],
            "unbalanced": res["unbalanced"], "dt": r.sim.dt, "particles": r.bodies.n}


def supports(steps):
    """The ``[[dirichlet]]`` and ``[[pressure]]`` rows: 2D, smooth platens, ``u_x = 0``
    on the left and the pressure on the right; 3D, rough platens (every component
    held, the top's ``u_y`` prescribed) and the pressure on the four sides."""
    top = -steps * STRAIN_STEP * SIZE[1]
    if DIM == 2:
        return ([{"boundary": "bottom", "component": "y", "value": 0.0},
                 {"boundary": "left", "component": "x", "value": 0.0},
                 {"boundary": "top", "component": "y", "value": top}],
                [{"boundary": "right", "value": P0}])
    rows = [{"boundary": b, "component": c, "value": top if (b, c) == ("top", "y") else 0.0}
            for b in ("bottom", "top") for c in "xyz"]
    return rows, [{"boundary": b, "value": P0} for b in ("left", "right", "front", "back")]


def problem(cells, steps, out_dir, relax=True, check_residual=True):
    """The validated biaxial (2D) or triaxial (3D) problem of ``cells`` elements
    (``relax`` False: RVE calls without relaxation, FEMxDEM's algorithm;
    ``check_residual`` False: Newton converges on the correction alone, FEMxDEM's
    criterion)."""
    from hmm.problem import validate_problem

    micro = dict(MICRO, relax=bool(relax))  # false: the loading steps, unrelaxed
    dirichlet, pressure = supports(steps)
    return validate_problem({
        "mesh": {"dim": DIM, "element": ELEMENT, "integration": "reduced",
                 "size": list(SIZE), "cells": list(cells)},
        "dirichlet": dirichlet,
        "pressure": pressure,
        "load": {"steps": steps},
        "micro": {"model": "dem", "packing": str(PACKING), **micro},
        "solver": dict(SOLVER, check_residual=bool(check_residual),
                       kinematics=KINEMATICS),
        "output": {"dir": str(out_dir)},
    }, source="hmm_vs_femxdem")


def run_ours(cells, steps, relax=True, check_residual=False):
    """Our solve of the problem (every rank calls this under mpiexec); rank 0
    returns the measurements, the others None."""
    out_dir = SCRATCH / f"ours_{_name(cells)}{'' if relax else '_fixed'}"
    return run_timed(problem(cells, steps, out_dir, relax, check_residual), out_dir)


def run_timed(prob, out_dir):
    """Run the validated problem ``prob`` with the solver's load steps and the farm's
    calls timed (every rank calls this under mpiexec): on rank 0 the measurements,
    with the Gauss-point weighted mean stress after every step (``mean_stress``,
    the micro models' stress: effective in a saturated run, whose mean pore pressure
    is ``mean_pore_pressure``) and volumetric strain; None on the others."""
    import h5py
    import numpy as np

    from hmm import coupling, farm
    from hmm.run import run_problem

    trials, step_walls = [], []
    for cls in (farm.SerialFarm, farm.MPIFarm):  # rank 0 drives the farm via trial()
        def timed_trial(self, deps, _orig=cls.trial):
            t0 = time.perf_counter()
            out = _orig(self, deps)
            trials.append({"wall": time.perf_counter() - t0,
                           "cost": float(np.sum(self.cost)),
                           "steps": [int(s) for s in self.steps]})
            return out
        cls.trial = timed_trial
    advance = coupling.Solver.advance

    def timed_advance(self, dt, on_iteration=None):
        t0 = time.perf_counter()
        its = advance(self, dt, on_iteration)
        step_walls.append(time.perf_counter() - t0)
        return its

    coupling.Solver.advance = timed_advance
    s = run_problem(prob, out_dir, overwrite=True, progress=False)
    if s is None:
        return None
    with h5py.File(out_dir / "fields.h5", "r") as f:
        w = f["gauss/weights"][()]
        frames = [f["steps"][k] for k in sorted(f["steps"], key=int)]
        stress = [(np.einsum("g,gij->ij", w, g["gauss/stress"][()]) / w.sum()).tolist()
                  for g in frames]
        pore = [float(w @ g["gauss/pore_pressure"][()] / w.sum()) for g in frames
                if "gauss/pore_pressure" in g]
        volume = [float(w @ np.trace(g["gauss/strain"][()], axis1=1, axis2=2) / w.sum())
                  for g in frames]
        top = f["curve/force/top"][()][:, 1].tolist()
    solve = trials[1:]  # the first trial is the solver's initial tangent
    _, comm = farm.mpi_world()
    return {"processes": 1 if comm is None else comm.Get_size(),
            "gauss_points": s["gauss_points"], "steps": s["steps"],
            "cuts": s["cuts"], "evaluations_per_step": s["iterations"],
            "step_wall": step_walls, "solve_time": s["solve_time"],
            "setup_time": s["total_time"] - s["solve_time"],
            "stage_wall": sum(t["wall"] for t in solve),
            "stage_cost": sum(t["cost"] for t in solve),
            "calls": len(solve) * s["gauss_points"],
            "dem_steps_per_call": float(np.mean([x for t in solve for x in t["steps"]])),
            "mean_stress": stress, "top_force": top,
            "mean_volumetric_strain": volume,
            **({"mean_pore_pressure": pore} if pore else {})}


def ours(cells, steps, procs, relax=True, check_residual=False):
    """Run :func:`run_ours` in a fresh process (under mpiexec for ``procs`` > 1)."""
    cmd = C.worker_command(__file__, ["ours", _name(cells), steps,
                                      "relax" if relax else "fixed",
                                      "residual" if check_residual else "correction"], procs)
    return C.run_result(cmd, C.worker_env(1), C.REPO)


# --------------------------------------------------------------------------- the peer
#: what FEMxDEM's simDEM imports as ``yadeimport``: Debian's yade executable (a Python
#: script) loaded as a module; it parses the command line, so it gets a clean one
YADEIMPORT = r'''"""YADE loaded as a module: the executable's script run in this namespace."""
import sys
import warnings

_argv = sys.argv
sys.argv = [(_argv or ["yade"])[0], "-n"]
try:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with open({yade!r}) as _fh:
            exec(compile(_fh.read(), {yade!r}, "exec"))
finally:
    sys.argv = _argv
'''

#: run by YADE after rve_vs_yade.py's script (which built the exported packing and
#: consolidated it): saves the scene that FEMxDEM loads at every Gauss point
YADE_SAVE = r'''
import json, os
exec(open(os.environ["HVF_DRIVE"]).read())
st = utils.getStressAndTangent(symmetry=True)
O.save(os.environ["HVF_SCENE"])
with open(os.environ["HVF_OUT"], "w") as fh:
    d = json.load(open(os.environ["RVE_YADE_IN"]))["dim"]
    json.dump({"stress": [[st[0][i, j] for j in range(d)] for i in range(d)],
               "unbalanced": utils.unbalancedForce(), "n_contacts": len(contacts()[0]),
               "dt": O.dt, "bodies": len(O.bodies),
               "yade_version": result.get("yade_version")}, fh)
'''

#: the FEMxDEM driver (run by Debian's python3 in PEER_DIR): the biaxial problem on
#: msFEM2D.MultiScale or the triaxial one on msFEM3D.MultiScale, settings from the
#: JSON file named by HVF_CONFIG
#: the part of every FEMxDEM driver after ``import ... as ms``: a pool that maps in
#: this process when one process is asked for (FEMxDEM's get_pool refuses one)
DRIVER_POOL = r'''

class InProcessPool:
    """FEMxDEM's pool interface, mapping in this process (its get_pool refuses one)."""

    def map(self, fn, items):
        return [fn(x) for x in items]

    def close(self):
        pass


if cfg["processes"] == 1:
    ms.get_pool = lambda mpi=False, threads=1: InProcessPool()
'''

FEMXDEM_DRIVER = r'''
import json, os, sys, time
import numpy as np

cfg = json.load(open(os.environ["HVF_CONFIG"]))
dim = len(cfg["size"])
import esys.escript as es
from esys.finley import Brick, Rectangle

if dim == 2:
    import msFEM2D as ms  # Escript and simDEM (which imports YADE through yadeimport)
    options = {"usePert": False}
else:
    import msFEM3D as ms
    import simDEM
    # msFEM3D calls shear, getStressAndTangent, ... which simDEM names with a 3D suffix
    for name in ("shear", "getStressAndTangent", "getVoidRatio", "avgRotation",
                 "getFabric"):
        setattr(ms, name, getattr(simDEM, name + "3D"))
    options = {}
''' + DRIVER_POOL + r'''if dim == 2:
    lx, ly = cfg["size"]
    nx, ny = cfg["cells"]
    dom = Rectangle(l0=lx, l1=ly, n0=nx, n1=ny, order=2, integrationOrder=2)
else:  # order 2: 20-node hexahedra; integrationOrder 2: 2 x 2 x 2 Gauss points
    lx, ly, lz = cfg["size"]
    nx, ny, nz = cfg["cells"]
    dom = Brick(l0=lx, l1=ly, l2=lz, n0=nx, n1=ny, n2=nz, order=2, integrationOrder=2)
ng = es.Function(dom).getX().getNumberOfDataPoints()
t0 = time.perf_counter()
prob = ms.MultiScale(domain=dom, ng=ng, np=cfg["processes"], rtol=cfg["rtol"],
                     verbose=False, **options)
setup = time.perf_counter() - t0

calls = []
dem_stage = prob.applyStrain_getStressTangentDEM


def timed_stage(st=es.Data()):
    grad = np.array(st.toListOfTuples()).reshape(-1, dim * dim)
    steps = [int(max(1e5 * np.max(np.abs(g)), 2)) for g in grad]  # as shear2D/3D
    t = time.perf_counter()
    out = dem_stage(st=st)
    calls.append({"wall": time.perf_counter() - t, "steps": steps})
    return out


prob.applyStrain_getStressTangentDEM = timed_stage
x = dom.getX()
bx = es.FunctionOnBoundary(dom).getX()
p0 = cfg["p0"]
if dim == 2:  # smooth platens, u_x = 0 on the left, the pressure on the right
    mask = es.whereZero(x[1]) * [0, 1] + es.whereZero(x[1] - ly) * [0, 1] \
        + es.whereZero(x[0]) * [1, 0]
    value = es.whereZero(x[1] - ly) * [0, -cfg["strain_step"] * ly]
    traction = es.whereZero(bx[0] - lx) * [-p0, 0]
else:  # rough platens (as triaxialRough), the pressure on the four sides
    mask = es.whereZero(x[1]) * [1, 1, 1] + es.whereZero(x[1] - ly) * [1, 1, 1]
    value = es.whereZero(x[1] - ly) * [0, -cfg["strain_step"] * ly, 0]
    traction = es.whereZero(bx[0]) * [p0, 0, 0] + es.whereZero(bx[0] - lx) * [-p0, 0, 0] \
        + es.whereZero(bx[2]) * [0, 0, p0] + es.whereZero(bx[2] - lz) * [0, 0, -p0]


def mean_stress():
    d = prob.getDomain()
    area = es.integrate(es.Scalar(1.0, es.Function(d)))
    return (np.array(es.integrate(prob.getCurrentStress())) / area).tolist()


stress, walls, evals = [mean_stress()], [], []
for k in range(cfg["steps"]):
    prob.initialize(f=traction, specified_u_mask=mask, specified_u_val=value)
    n0 = len(calls)
    t = time.perf_counter()
    prob.solve(iter_max=cfg["iter_max"])
    walls.append(time.perf_counter() - t)
    evals.append(len(calls) - n0)
    stress.append(mean_stress())
prob.exitSimulation()
steps = [s for c in calls for s in c["steps"]]
print("RESULT " + json.dumps({
    "processes": cfg["processes"], "gauss_points": ng, "steps": cfg["steps"],
    "evaluations_per_step": evals, "step_wall": walls, "solve_time": sum(walls),
    "setup_time": setup, "stage_wall": sum(c["wall"] for c in calls),
    "calls": len(calls) * ng, "dem_steps_per_call": float(np.mean(steps)),
    "mean_stress": stress}), flush=True)
'''


def peer_paths():
    """``(paths, reason)``: where Debian's YADE and Escript put what the peer needs,
    found from their launch scripts, or ``(None, why not)``."""
    exe = os.environ.get("YADE", "yade")
    yade = shutil.which(exe)
    if yade is None:
        return None, f"YADE is not installed (no '{exe}' executable on PATH)"
    yade = os.path.realpath(yade)  # Debian's yade -> yade-double, a Python script
    head = Path(yade).read_text(errors="replace")
    python = head.splitlines()[0][2:].strip() if head.startswith("#!") else ""
    m = re.search(r"sys\.path\.insert\(1,\s*'([^']+)'\)", head)
    module = Path(m.group(1)) / "yade" / "FEMxDEM" if m else None
    if not python or module is None or not (module / "msFEM2D.py").is_file():
        return None, "YADE's FEMxDEM module (yade/FEMxDEM/msFEM2D.py) was not found"
    launcher = shutil.which("run-escript3") or shutil.which("run-escript")
    root = None
    if launcher:
        m = re.search(r"^\s*ESCRIPT_ROOT=(\S+)", Path(launcher).read_text(errors="replace"),
                      re.MULTILINE)
        root = Path(m.group(1)) if m else None
    if root is None or not (root / "esys" / "escript").is_dir():
        return None, "Escript is not installed (python3-escript: no run-escript3)"
    paths = {"yade": yade, "python": python, "femxdem": str(module),
             "escript": str(root), "escript_lib": str(root / "lib")}
    env = peer_env(paths)
    p = subprocess.run([python, "-c", "import esys.escript, esys.finley"], env=env,
                       stdin=subprocess.DEVNULL, capture_output=True, text=True,
                       timeout=120, check=False)
    if p.returncode != 0:
        return None, ("Escript does not import under " + python + ": "
                      + (p.stderr.strip().splitlines() or ["?"])[-1])
    return paths, ""


def peer_env(paths, extra=()):
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONWARNINGS="ignore")
    env.pop("DISPLAY", None)
    env["PYTHONPATH"] = os.pathsep.join([paths["escript"], paths["femxdem"],
                                         str(PEER_DIR)])
    env["LD_LIBRARY_PATH"] = os.pathsep.join(
        x for x in (paths["escript_lib"], os.environ.get("LD_LIBRARY_PATH")) if x)
    env.update(extra)
    return env


def prepare_peer(paths):
    """YADE's RVE scene (``0.yade.gz``) from the export, and the modules FEMxDEM
    imports from its working directory."""
    PEER_DIR.mkdir(parents=True, exist_ok=True)
    (PEER_DIR / "yadeimport.py").write_text(YADEIMPORT.format(yade=paths["yade"]))
    (PEER_DIR / "femxdem_driver.py").write_text(FEMXDEM_DRIVER)
    (PEER_DIR / "drive.py").write_text(RV.YADE_SCRIPT)
    (PEER_DIR / "save_scene.py").write_text(YADE_SAVE)
    env = dict(os.environ, OMP_NUM_THREADS="1", RVE_YADE_IN=str(EXPORT),
               RVE_YADE_OUT=str(PEER_DIR / "consolidation.json"),
               RVE_YADE_MODE="compress", RVE_YADE_AXIAL="0",
               HVF_DRIVE=str(PEER_DIR / "drive.py"), HVF_SCENE=str(PEER_DIR / "0.yade.gz"),
               HVF_OUT=str(PEER_DIR / "scene.json"))
    env.pop("DISPLAY", None)
    p = subprocess.run([paths["yade"], "-j", "1", "-n", "-x", "save_scene.py"],
                       cwd=PEER_DIR,
                       env=env, stdin=subprocess.DEVNULL, capture_output=True, text=True,
                       timeout=3600, check=False)
    if not (PEER_DIR / "scene.json").exists():
        tail = (p.stderr or p.stdout).strip().splitlines()[-10:]
        raise RuntimeError(f"YADE failed (rc={p.returncode}): " + " | ".join(tail))
    return json.loads((PEER_DIR / "scene.json").read_text())


def peer(paths, cells, steps, procs):
    """One FEMxDEM run of the problem."""
    cfg = {"size": list(SIZE), "cells": list(cells), "steps": steps, "processes": procs,
           "rtol": RTOL, "iter_max": ITER_MAX, "strain_step": STRAIN_STEP, "p0": P0}
    path = PEER_DIR / f"config_{_name(cells)}_{procs}.json"
    path.write_text(json.dumps(cfg))
    env = peer_env(paths, {"HVF_CONFIG": str(path)})
    return C.run_result([paths["python"], "femxdem_driver.py"], env, PEER_DIR)


# --------------------------------------------------------------------------- comparison
def per_run(r, peer=False):
    """Per load step and per Gauss-point call figures of one run."""
    n = max(1, len(r["step_wall"]))
    evals = r["evaluations_per_step"]
    out = {"processes": r["processes"], "gauss_points": r["gauss_points"],
           "load_steps": len(r["step_wall"]),
           "wall_per_load_step": r["solve_time"] / n,
           "step_wall": r["step_wall"],
           "wall_per_rve_call": r["stage_wall"] / max(1, r["calls"]),
           "rve_calls": r["calls"],
           "evaluations_per_step": evals,
           # Newton corrections: FEMxDEM evaluates once more after its last one
           "newton_iterations": [e - 1 for e in evals] if peer else evals,
           "dem_steps_per_call": r["dem_steps_per_call"],
           "setup_time": r["setup_time"]}
    if "stage_cost" in r:  # ours: the RVEs' own time, without transfers and waiting
        out["rve_time_per_call"] = r["stage_cost"] / max(1, r["calls"])
    return out


def deviation(ours_run, peer_run):
    """Largest differences of the mean stress over the common steps."""
    import numpy as np

    a, b = np.array(ours_run["mean_stress"]), np.array(peer_run["mean_stress"])
    n = min(len(a), len(b))
    a, b = a[:n], b[:n]
    syy = np.abs(a[:, 1, 1] - b[:, 1, 1]).max() / np.abs(a[:, 1, 1]).max()
    qa, qb = a[:, 0, 0] - a[:, 1, 1], b[:, 0, 0] - b[:, 1, 1]
    dq = np.abs(qa - qb)[1:].max() / max(np.abs(qa)[1:].max(), 1e-300) if n > 1 else None
    return {"max_rel_stress_deviation": float(syy),
            "max_rel_deviator_deviation": None if dq is None else float(dq),
            "compared_steps": n - 1}


def visualize(data):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    sizes = [k for k, v in data["sizes"].items() if v.get("curves")]
    fig = Figure(figsize=(4.8 * max(1, len(sizes)), 4.0), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, max(1, len(sizes)), squeeze=False)[0]
    lines = (("ours", "ko-", "hmm"), ("ours_no_relaxation", "b^-.", "hmm, no relaxation"),
             ("femxdem", "rs--", "FEMxDEM"))
    for ax, size in zip(axes, sizes, strict=False):
        row = data["sizes"][size]
        for key, style, name in lines:
            c = row["curves"].get(key)
            if c is None:
                continue
            ea = [100.0 * e for e in c["axial_strain"]]
            ax.plot(ea, [-s / 1e3 for s in c["sigma_yy"]], style, ms=5, mfc="none",
                    label=f"{name}: -σyy")
            ax.plot(ea, [-s / 1e3 for s in c["sigma_xx"]], style[0] + ":", lw=1)
        title = f"{size} mesh, {row['gauss_points']} Gauss points, {row['kinematics']}"
        dev = row.get("max_rel_stress_deviation")
        if dev is not None:
            title += (f"\nmax |Δσyy| / max |σyy|: {100 * dev:.1f} % "
                      f"({100 * row['max_rel_stress_deviation_no_relaxation']:.1f} % "
                      f"without relaxation)")
        ax.set(xlabel="axial strain [%]",
               ylabel="mean stress [kPa] (compression +; dotted: -σxx)", title=title)
        ax.title.set_fontsize(9)
        ax.legend(fontsize=8, loc="lower right")
    return fig


#: our two runs: the solver as it is, and with FEMxDEM's RVE call (no relaxation)
VARIANTS = (("ours", "hmm", True), ("ours_no_relaxation", "hmm, no relaxation", False))
#: per-size figures, taken over the process counts (speedups: the smallest)
SUMMARY = ("speedup", "speedup_rve_call", "speedup_no_relaxation",
           "speedup_rve_call_no_relaxation", "max_rel_stress_deviation",
           "max_rel_deviator_deviation", "max_rel_stress_deviation_no_relaxation",
           "max_rel_deviator_deviation_no_relaxation",
           "max_rel_stress_deviation_relaxation")


def measure(size, procs, steps, peer_steps, paths, runs):
    """Our runs and the peer's on one mesh, for each process count, interleaved."""
    cells = _size(size)
    row = {"cells": list(cells), "gauss_points": 2 ** DIM * math.prod(cells),
           "processes": procs, "load_steps": steps, "kinematics": KINEMATICS,
           "max_axial_strain": STRAIN_STEP * steps, "by_processes": {}, "curves": {}}
    for p in procs:
        entry, results = {}, {}
        for key, label, relax in VARIANTS:
            load = C.loadavg()
            r = ours(cells, steps, p, relax)
            runs.append({"size": size, "code": key, "processes": p, "loadavg": load, **r})
            if not r.get("ok"):
                raise RuntimeError(f"{label}, {size} on {p} processes failed: "
                                   + r["error"])
            results[key], entry[key] = r, per_run(r)
            print(f"{size} {label}, {p} proc: {entry[key]['wall_per_load_step']:.2f} s "
                  f"per load step, {1e3 * entry[key]['wall_per_rve_call']:.1f} ms per "
                  f"call, evaluations {r['evaluations_per_step']}, sigma_yy "
                  f"{[round(x[1][1] / 1e3, 1) for x in r['mean_stress']]} kPa", flush=True)
        if paths is not None:
            load = C.loadavg()
            r = peer(paths, cells, peer_steps, p)
            runs.append({"size": size, "code": "femxdem", "processes": p, "loadavg": load,
                         **r})
            if r.get("ok"):
                results["femxdem"], entry["femxdem"] = r, per_run(r, peer=True)
                them = entry["femxdem"]
                for key, suffix in (("ours", ""), ("ours_no_relaxation", "_no_relaxation")):
                    us = entry[key]
                    entry["speedup" + suffix] = (them["wall_per_load_step"]
                                                 / us["wall_per_load_step"])
                    entry["speedup_rve_call" + suffix] = (them["wall_per_rve_call"]
                                                          / us["wall_per_rve_call"])
                    for k, v in deviation(results[key], r).items():
                        entry[k if k == "compared_steps" else k + suffix] = v
                print(f"{size} FEMxDEM, {p} proc: {them['wall_per_load_step']:.2f} s per "
                      f"load step, {1e3 * them['wall_per_rve_call']:.1f} ms per call, "
                      f"evaluations {r['evaluations_per_step']}, sigma_yy "
                      f"{[round(x[1][1] / 1e3, 1) for x in r['mean_stress']]} kPa; "
                      f"speedup {entry['speedup']:.2f} ({entry['speedup_no_relaxation']:.2f}"
                      f" without relaxation), max |dsigma_yy| / max |sigma_yy| "
                      f"{entry['max_rel_stress_deviation']:.4f} "
                      f"({entry['max_rel_stress_deviation_no_relaxation']:.4f})", flush=True)
            else:
                entry["femxdem_error"] = r["error"]
                print(f"{size} FEMxDEM, {p} proc failed: {r['error']}", flush=True)
        relaxation = deviation(results["ours"], results["ours_no_relaxation"])
        entry["max_rel_stress_deviation_relaxation"] = relaxation[
            "max_rel_stress_deviation"]
        row["by_processes"][str(p)] = entry
        for key, r in results.items():
            row["curves"].setdefault(key, {
                "axial_strain": [STRAIN_STEP * k for k in range(len(r["mean_stress"]))],
                "sigma_xx": [x[0][0] for x in r["mean_stress"]],
                "sigma_yy": [x[1][1] for x in r["mean_stress"]]})
    entries = row["by_processes"]
    first = entries[str(procs[0])]
    for what in ("newton_iterations", "evaluations_per_step", "dem_steps_per_call"):
        row[what] = {k: first[k][what] for k in ("ours", "ours_no_relaxation", "femxdem")
                     if k in first}
    for what in ("wall_per_load_step", "wall_per_rve_call"):
        row[what] = {p: {k: e[k][what] for k in ("ours", "ours_no_relaxation", "femxdem")
                         if k in e} for p, e in entries.items()}
    measured = [e for e in entries.values() if "speedup" in e]
    if not measured:  # no peer: our own comparison still summarises
        row["max_rel_stress_deviation_relaxation"] = max(
            e["max_rel_stress_deviation_relaxation"] for e in entries.values())
    row["speedup_by_processes"] = {p: e["speedup"] for p, e in entries.items()
                                   if "speedup" in e}
    for key in SUMMARY if measured else ():
        pick = max if key.startswith("max_") else min
        row[key] = pick((e[key] for e in measured if e.get(key) is not None),
                        default=None)
    return row


def _rounded(stress):
    return [round(x) for row in stress for x in row]


def _size(s):
    cells = tuple(int(v) for v in s.lower().split("x"))
    if len(cells) != DIM:
        raise SystemExit(f"a {DIM}D mesh size has {DIM} numbers, not {s!r}")
    return cells


def _name(cells):
    return "x".join(str(n) for n in cells)


def published(spec, procs, save):
    """Ours alone on the published problem size, ``spec`` = "NXxNY:STEPS" (FEMxDEM's
    biaxial example: 8x16 elements, 512 Gauss points, 100 load steps), with
    FEMxDEM's RVE call and with relaxation, on ``procs`` processes, Newton converging
    on the correction alone (FEMxDEM's criterion: past the peak the residual of
    400-disk RVEs sits above 1e-2): the solve's wall time, Newton evaluations, cuts
    and the mean stress curve. ``save(result)`` is called after every run, so that a
    long second run does not hold the first one's result back."""
    size, n_steps = spec.split(":")
    rows = {}
    out = {"mesh": size, "load_steps": int(n_steps), "processes": procs, "runs": rows}
    for variant, _, relax in sorted(VARIANTS, key=lambda v: v[2]):  # unrelaxed first
        kind = "relax" if relax else "fixed"
        if kind not in C.env_list("PUBLISHED_RUNS", "fixed relax"):
            continue
        r = ours(_size(size), int(n_steps), procs, relax, check_residual=False)
        if not r.get("ok"):
            rows[variant] = {"ok": False, "error": r["error"]}
            print(f"{size} x {n_steps} steps, {variant}: {r['error']}", flush=True)
            continue
        rows[variant] = {k: r[k] for k in ("processes", "gauss_points", "steps", "cuts",
                                           "evaluations_per_step", "solve_time",
                                           "setup_time", "dem_steps_per_call",
                                           "mean_stress")}
        evals = r["evaluations_per_step"]
        print(f"{size} x {n_steps} steps, {variant}, {procs} processes: solve "
              f"{r['solve_time']:.0f} s, {sum(evals) / len(evals):.2f} evaluations per "
              f"step, {r['cuts']} cuts", flush=True)
        save(out)
    return out


def main():
    """``PUBLISHED="8x16:100"`` runs :func:`published` only (``PUBLISHED_PROCS``, 2)
    and adds it to the JSON of an earlier comparison; otherwise the comparison."""
    if os.environ.get("PUBLISHED"):
        if DIM != 2:
            raise SystemExit("PUBLISHED is the 2D biaxial example's size: DIM=2 only")
        data = json.loads(OUT.read_text()) if OUT.exists() else {}
        prep = C.run_worker(__file__, ["prepare"], threads=1)
        if not prep.get("ok"):
            raise RuntimeError("preparing the packing failed: " + prep["error"])
        def save(result):
            data["published"] = dict(result, date=C.now(), revision=C.git_revision(),
                                     loadavg=C.loadavg())
            C.write_json(OUT, data)

        save(published(os.environ["PUBLISHED"], C.env_int("PUBLISHED_PROCS", 2), save))
        return
    default_steps = C.env_int("STEPS", 3)
    sizes = {}
    for item in C.env_list("SIZES", DEFAULT_SIZES):
        size, _, n = item.partition(":")
        sizes[size] = int(n) if n else default_steps
    peer_cap = os.environ.get("PEER_STEPS")
    procs = [int(p) for p in C.env_list("PROCS", "2")]
    data = {"benchmark": OUT.stem, "date": C.now(), "machine": C.machine_info(),
            "versions": C.our_versions(),
            "kinematics": KINEMATICS,
            "settings": {"sample": list(SIZE), "dim": DIM,
                         "element": f"{ELEMENT} ({2 ** DIM} Gauss points)",
                         "platens": "smooth" if DIM == 2 else "rough",
                         "p0": P0, "strain_step": STRAIN_STEP, "steps": sizes,
                         "peer_steps": peer_cap, "processes": procs, "rtol": RTOL,
                         "femxdem_iter_max": ITER_MAX, "micro": MICRO, "solver": SOLVER,
                         "yade_thickness": YADE_THICKNESS, "packing": RV.SETUP[DIM],
                         "radius": list(RV.RADIUS), "density": RV.DENSITY},
            "sizes": {}}
    if peer_cap is not None:
        data["note"] = (f"the peer ran at most {peer_cap} load steps (time budget): "
                        f"speedups are per load step and per call, the stress "
                        f"deviation covers its steps")
    t0 = time.perf_counter()
    prep = C.run_worker(__file__, ["prepare"], threads=1)
    if not prep.get("ok"):
        raise RuntimeError("preparing the packing failed: " + prep["error"])
    prep.pop("ok")
    data["packing"] = {"ours": prep}
    print(f"packing ready ({time.perf_counter() - t0:.0f} s): ours sigma = "
          f"{_rounded(prep['stress'])} Pa", flush=True)
    paths, reason = peer_paths()
    if paths is not None:
        try:
            data["packing"]["yade"] = prepare_peer(paths)
            data["versions"]["yade"] = data["packing"]["yade"].get("yade_version")
            print(f"YADE scene ready: sigma = "
                  f"{_rounded(data['packing']['yade']['stress'])} Pa",
                  flush=True)
        except (RuntimeError, OSError, subprocess.SubprocessError) as err:
            paths, reason = None, f"YADE could not prepare the RVE scene: {err}"
    if paths is None:
        data["status"] = "peer_skipped"
        data["reason"] = reason
        print(f"FEMxDEM skipped: {reason}", flush=True)
    runs = []
    for size, steps in sizes.items():
        peer_steps = min(steps, int(peer_cap)) if peer_cap else steps
        data["sizes"][size] = measure(size, procs, steps, peer_steps, paths, runs)
    data["max_axial_strain"] = max(STRAIN_STEP * steps for steps in sizes.values())
    done = [r for r in data["sizes"].values() if r.get("speedup") is not None]
    for key in SUMMARY:
        pick = max if key.startswith("max_") else min
        data[key] = pick((r[key] for r in done), default=None)
    data["runs"] = runs
    data["wall_time"] = time.perf_counter() - t0
    data["loadavg_end"] = C.loadavg()
    data.setdefault("status", "ok")
    C.write_json(OUT, data)
    FIGURE.parent.mkdir(parents=True, exist_ok=True)
    visualize(data).savefig(FIGURE, dpi=120)
    print(f"speedup (smallest over sizes and processes) {data['speedup']}, max relative "
          f"sigma_yy deviation {data['max_rel_stress_deviation']}; wrote "
          f"{C.display_path(OUT)}, {C.display_path(FIGURE)}")


def worker(args):
    if args[0] == "prepare":
        C.emit_result(prepare_ours())
    elif args[0] == "ours":
        r = run_ours(_size(args[1]), int(args[2]), args[3] == "relax",
                     args[4] != "correction" if len(args) > 4 else False)
        if r is not None:
            C.emit_result(r)


if __name__ == "__main__":
    C.entry(main, worker)
