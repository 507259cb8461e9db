"""Stability map: where each solver of the toolkit stops working, and how it says so.

Six panels, each a sweep of one control parameter past the line where the solver fails:

a. **DEM spheres, explicit integration.** Precompressed periodic lattices (36 disks on
   a hexagonal lattice, 32 spheres on a face-centred cubic one: triangulated, hence
   stable under pressure with normal springs alone; undamped ``LinearSpring(kn)``,
   contacts never open) with random velocities, run for ``T = 100 dt_crit`` at ``dt = f x dt_crit``
   (``allow_unstable_dt=True``). Energy error ``max |E(t) - E(0)| / K(0)`` (``E``
   kinetic + elastic; ``K(0)`` the kinetic energy the lattice starts with, which is
   also the energy of its motion: it starts at rest positions). Failed: a
   :class:`dem.SimulationError` or an error above 1. Each lattice's own Verlet limit
   ``2 / omega_max``, from the eigenvalues of its contact stiffness matrix, is drawn
   for comparison, and the step the engine refuses from. A third lattice, fcc with
   sticking tangential springs ``kt = kn / 2`` and random spins, crosses the spin
   mode's line (``1 / sqrt(40/7)`` of dt_crit).
b. **DEM polyhedra.** Two random convex polyhedra, spinning, colliding edge on edge
   (the conserving scene of ``tests/dem/test_shape_dynamics.py``), ``T = 400 dt_crit``.
c. **Peridynamics.** A free LPS plate (60 points, the energy test of
   ``tests/dem/test_peridynamics.py``) vibrating, ``T = 80 dt_crit``; energy kinetic +
   strain.
d. **RVE relaxation.** A consolidated periodic packing of 60 disks takes an axial strain
   increment; steps to relax to the unbalanced-force tolerance against the increment
   and against Cundall damping; :class:`dem.rve.RelaxationError` where the step cap is
   reached.
e. **Macro Newton.** Plane-strain block on rollers, hyperbolic micro law (a shear
   stress that saturates: a uniaxial limit load ``q_lim = 2 G0 gamma_ref``), under
   displacement control and under a top pressure below and above ``q_lim``: Newton
   iterations and step cuts against the number of load steps; above the limit the
   solver cuts to ``min_step`` and stops with :class:`hmm.coupling.SolverError`.
f. **Contact detection (ADMM).** Two boxes (3D): faces nearly parallel (tilt), deep
   penetration, thin plates crossing; cold iterations to 1e-8; then the fallback: a
   stale warm start with a small iteration cap fails warm, succeeds cold, and a cap too
   small for a cold solve stops ``dem.Simulation(detection="admm")`` with an error that
   names the pair. Non-convex parts: a cube thrown into the inner corner of an L of
   two boxes, diagonally (a crease of the summed SDFs) and twice as fast sideways.

usage::

    python benchmarks/stability_map.py           # full sweep (a few minutes on one core)
    python benchmarks/stability_map.py --quick   # coarse grids (for a smoke run)
    python benchmarks/stability_map.py --figure  # redraw the chart from the JSON

writes ``benchmarks/results/stability_map.json`` and ``docs/figures/stability_map.png``.
"""

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")  # small scenes: one thread
os.environ.setdefault("MPLBACKEND", "Agg")

import warnings

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import dem
from dem.observers import elastic_energy, kinetic_energy

OUT = REPO / "benchmarks" / "results" / "stability_map.json"
#: the results' sections, one a panel of the chart
PANELS = ("spheres", "polyhedra", "peridynamics", "rve", "newton", "admm")
PNG = REPO / "docs" / "figures" / "stability_map.png"

FULL_GRID = [0.02, 0.05, 0.1, 0.2, 0.3, 0.4, 0.44, 0.5, 0.55, 0.6, 0.625, 0.65, 0.675, 0.7,
             0.75, 0.8, 0.9, 0.95, 1.0, 1.05, 1.1, 1.25, 1.5]
QUICK_GRID = [0.02, 0.1, 0.3, 0.5, 0.6, 0.65, 0.7, 0.8, 1.0, 1.05, 1.5]
N_SAMPLES = 50  # energy samples per run
FAIL = 1.0  # energy error that counts as a failure


# --------------------------------------------------------------------------- a. spheres
R, RHO, KN = 0.01, 2500.0, 1e5
SQUEEZE = 0.02  # precompression: overlap 2 SQUEEZE R per contact


def lattice(kind, side, seed=0):
    """A precompressed periodic lattice with random velocities (displacements about a
    quarter of the overlap: contacts never open). Returns (bodies, box)."""
    from dem.neighbors import Box

    a = 2.0 * R * (1.0 - SQUEEZE)
    if kind == "hex":
        pos = np.array([[(i + 0.5 * (j % 2)) * a, j * a * math.sqrt(3.0) / 2.0]
                        for j in range(side) for i in range(side)])
        length = np.array([side * a, side * a * math.sqrt(3.0) / 2.0])
    else:  # fcc: ``side`` cubic cells of 4 spheres per axis
        c = a * math.sqrt(2.0)
        basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]]) * c
        cells = np.stack(np.meshgrid(*[np.arange(side) * c] * 3, indexing="ij"),
                         -1).reshape(-1, 3)
        pos = (cells[:, None, :] + basis[None]).reshape(-1, 3)
        length = np.full(3, side * c)
    dim = pos.shape[1]
    bodies = dem.Bodies.spheres(pos, radius=R, density=RHO)
    rng = np.random.default_rng(seed)
    omega = math.sqrt(KN / bodies.mass[0])
    bodies.vel[:] = rng.normal(0.0, 1.0, bodies.vel.shape) * 0.25 * SQUEEZE * R * omega
    bodies.vel -= bodies.vel.mean(axis=0)
    lo = -0.5 * a * np.ones(dim)
    return bodies, Box(lo, lo + length, [True] * dim)


def verlet_limit(bodies, box, kn):
    """``2 / omega_max`` [s] of the lattice's contact network (normal springs, the
    linearisation about the rest positions, precompression's geometric term left out)."""
    n, d = bodies.pos.shape
    length = box.hi - box.lo
    k = np.zeros((n * d, n * d))
    for i in range(n):
        for j in range(i + 1, n):
            dx = bodies.pos[j] - bodies.pos[i]
            dx -= length * np.rint(dx / length)
            dist = np.linalg.norm(dx)
            if dist < bodies.radius[i] + bodies.radius[j]:
                e = np.outer(dx, dx) / dist**2 * kn
                si, sj = slice(i * d, i * d + d), slice(j * d, j * d + d)
                k[si, si] += e
                k[sj, sj] += e
                k[si, sj] -= e
                k[sj, si] -= e
    m = np.repeat(bodies.mass, d)
    lam = np.linalg.eigvalsh(k / np.sqrt(np.outer(m, m)))
    return 2.0 / math.sqrt(lam.max())


def energy_run(make, factors, horizon, energy):
    """Run ``make(f)`` (a simulation at dt = f dt_crit) for ``horizon`` x dt_crit at each
    factor; return rows (factor, error, failure message or None, steps)."""
    rows = []
    for f in factors:
        sim = make(f)
        e0, k0 = energy(sim)
        n = max(N_SAMPLES, round(horizon / f))
        chunk = max(1, n // N_SAMPLES)
        err, why = 0.0, None
        try:
            for _ in range(N_SAMPLES):
                sim.run(chunk)
                err = max(err, abs(energy(sim)[0] - e0) / k0)
                if not math.isfinite(err):
                    why = "non-finite energy"
                    break
        except dem.SimulationError as exc:
            why = str(exc)
        rows.append({"factor": f, "energy_error": err if math.isfinite(err) else None,
                     "error": why, "steps": chunk * N_SAMPLES,
                     "failed": why is not None or err > FAIL})
    return rows


def threshold(rows):
    """(largest factor that passed with every smaller one, smallest that failed)."""
    ok = None
    for r in sorted(rows, key=lambda r: r["factor"]):
        if r["failed"]:
            return ok, r["factor"]
        ok = r["factor"]
    return ok, None


def spun_lattice(side, seed=0):
    """The fcc lattice with random spins as well (small against the overlap)."""
    bodies, box = lattice("fcc", side, seed)
    rng = np.random.default_rng(seed + 1)
    omega = math.sqrt(KN / bodies.mass[0])
    bodies.ang_vel[:] = rng.normal(0.0, 1.0, bodies.ang_vel.shape) * 0.25 * SQUEEZE * omega
    return bodies, box


def sphere_panel(grid):
    normal = dem.LinearSpring(kn=KN)
    # sticking tangential springs kt = kn / 2: their rotation-coupled 1.75 kn sets
    # dt_crit, and the lattice's fastest mode is every sphere spinning the same way,
    # sqrt(40/7) times the two-body frequency (tests/test_stability.py)
    tangential = dem.LinearSpring(kn=KN, kt=0.5 * KN, mu=10.0)

    def energy(sim):
        e = sum(kinetic_energy(sim.bodies)) + elastic_energy(sim)
        return e, sum(kinetic_energy(sim.bodies)) if sim.step == 0 else None

    cases = {"hex": (lambda: lattice("hex", 6), normal, None),
             "fcc": (lambda: lattice("fcc", 2), normal, None),
             "fcc, kt = kn/2": (lambda: spun_lattice(2), tangential,
                                1.0 / math.sqrt(40.0 / 7.0))}
    out = {}
    for kind, (build, law, limit) in cases.items():
        bodies, box = build()
        probe = dem.Simulation(bodies.copy(), law, box=box, dt=1e-9)
        dt_crit = probe.dt_crit

        def make(f, build=build, law=law, dt_crit=dt_crit):
            b, bx = build()
            return dem.Simulation(b, law, box=bx, dt=f * dt_crit, threads=1,
                                  allow_unstable_dt=True)

        rows = energy_run(make, grid, 100.0, _first_kinetic(energy))
        ok, bad = threshold(rows)
        out[kind] = {"n": bodies.n, "dim": bodies.dim, "dt_crit": dt_crit,
                     "verlet_limit": (verlet_limit(bodies, box, KN) / dt_crit
                                      if limit is None else limit),
                     "refused_from": probe.dt_stable / dt_crit,
                     "rows": rows, "stable_up_to": ok, "fails_at": bad}
        log(f"spheres {kind}: stable to {ok}, fails at {bad}, lattice limit "
            f"{out[kind]['verlet_limit']:.3f}")
    return out


def _first_kinetic(energy):
    """Wrap ``energy(sim) -> (E, K0 or None)`` so the first call fixes K0."""
    state = {}

    def call(sim):
        e, k = energy(sim)
        if sim.step == 0 or "k0" not in state:
            state["k0"] = k
        return e, state["k0"]

    return call


# --------------------------------------------------------------------------- b. polyhedra
def polyhedra(seed=2):
    from dem.shapes import ConvexPolyhedron

    rng = np.random.default_rng(seed)
    shapes = [ConvexPolyhedron.from_vertices(0.02 * rng.normal(size=(12, 3)))
              for _ in range(2)]
    q = rng.normal(size=(2, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    b = dem.Bodies.empty(3)
    b.add_shapes(shapes[0], [[0.0, 0.0, 0.0]], 1000.0, rot=q[:1], vel=[[1.0, 0.0, 0.0]],
                 ang_vel=[[3.0, -2.0, 1.0]])
    b.add_shapes(shapes[1], [[0.0416, 0.01, -0.008]], 1000.0, rot=q[1:],
                 vel=[[-0.5, 0.05, 0.0]], ang_vel=[[-1.0, 2.0, 4.0]])
    return b


def polyhedra_panel(grid):
    law = dem.LinearSpring(kn=1e5)

    def make(f):
        sim = dem.Simulation(polyhedra(), law, threads=1)
        sim.dt = f * sim.dt_crit
        return sim

    def energy(sim):
        k = sum(kinetic_energy(sim.bodies))
        return k + elastic_energy(sim), k

    rows = energy_run(make, grid, 400.0, _first_kinetic(energy))
    ok, bad = threshold(rows)
    log(f"polyhedra: stable to {ok}, fails at {bad}")
    probe = make(1.0)
    return {"dt_crit": probe.dt_crit, "refused_from": probe.dt_stable / probe.dt_crit,
            "rows": rows, "stable_up_to": ok, "fails_at": bad}


# --------------------------------------------------------------------------- c. PD
def pd_panel(grid):
    from dem import peridynamics as pd

    dx = 0.01
    mat = pd.LPS(E=1e9, nu=0.25, density=1000.0, plane="stress", surface_correction=True)

    def plate(**kw):
        b = dem.Bodies.empty(2)
        ids = pd.add_points(b, pd.lattice([0, 0], [0.1, 0.06], dx), dx, 1000.0,
                            thickness=0.01)
        return pd.PDSimulation(b, mat, ids, 3.0 * dx, threads=1, **kw)

    dt_crit = plate().dt_crit

    def make(f):
        sim = plate(dt=f * dt_crit, allow_unstable_dt=True)
        x, y = (sim.x0 / [0.1, 0.06]).T
        sim.bodies.vel[:, 0] = 0.5 * np.cos(np.pi * x)
        sim.bodies.vel[:, 1] = 0.3 * np.cos(np.pi * y) * np.sin(np.pi * x)
        rng = np.random.default_rng(0)  # excite the highest modes too
        sim.bodies.vel += 0.05 * rng.normal(size=sim.bodies.vel.shape)
        return sim

    def energy(sim):
        k = sim.kinetic_energy()
        return k + sim.strain_energy(), k

    rows = energy_run(make, grid, 80.0, _first_kinetic(energy))
    ok, bad = threshold(rows)
    log(f"peridynamics: stable to {ok}, fails at {bad}")
    return {"dt_crit": dt_crit, "rows": rows, "stable_up_to": ok, "fails_at": bad}


# --------------------------------------------------------------------------- d. RVE
def rve_panel(quick):
    from dem import rve

    law = dem.LinearSpring(kn=1e8, kt=5e7, mu=0.5)
    packing = rve.generate(2, 60, (0.8e-3, 1.2e-3), law, p0=1e5, friction=0.0, seed=5,
                           damping=0.5)
    cap = 20_000
    packing.max_relax_steps = cap
    start = packing.snapshot()
    strains = [1e-5, 1e-4, 1e-3, 1e-2] if quick else [1e-5, 3e-5, 1e-4, 3e-4, 1e-3,
                                                        3e-3, 1e-2]
    dampings = [0.0, 0.02, 0.5] if quick else [0.0, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 0.8]
    rows = []
    for c in dampings:
        for s in strains:
            packing.restore(start)
            packing.sim.damping = c
            deps = np.diag([0.0, -s])
            n_load = math.ceil(s / packing.max_step_strain)
            row = {"damping": c, "strain": s, "loading_steps": n_load}
            t0 = time.perf_counter()
            try:
                packing.apply_strain(deps)
                row["relax_steps"] = packing.last_relax_steps - n_load
                row["error"] = None
            except rve.RelaxationError as exc:
                row["relax_steps"] = None
                row["error"] = str(exc)
            except dem.SimulationError as exc:  # a blow-up: reported too
                row["relax_steps"] = None
                row["error"] = f"{type(exc).__name__}: {exc}"
            row["seconds"] = time.perf_counter() - t0
            rows.append(row)
            log(f"rve damping {c} strain {s:g}: {row['relax_steps']} steps"
                + (" (RelaxationError)" if row["error"] else ""))
    packing.restore(start)
    return {"n": packing.bodies.n, "tol": packing.tol, "max_relax_steps": cap,
            "max_step_strain": packing.max_step_strain, "rows": rows}


# --------------------------------------------------------------------------- e. Newton
E_MACRO, NU, GAMMA_REF = 1e6, 0.3, 1e-3


def newton_case(control, n_steps, level=0.95, min_step=1.0 / 64.0):
    """One load history in ``n_steps`` equal steps; returns a row."""
    from hmm.coupling import Solver, SolverError, SolverSettings, Supports
    from hmm.farm import SerialFarm
    from hmm.macro import Macro, structured_mesh
    from hmm.micro import Hyperbolic, lame

    macro = Macro(structured_mesh("quad1", [1.0, 1.0], [2, 2]), "quad1")
    farm = SerialFarm([Hyperbolic(E_MACRO, NU, GAMMA_REF) for _ in range(macro.n_gp)])
    g0 = lame(E_MACRO, NU)[1]
    q_lim = 2.0 * g0 * GAMMA_REF
    left, bottom, top = macro.dofs("left", 0), macro.dofs("bottom", 1), macro.dofs("top", 1)
    if control == "displacement":
        dofs = np.concatenate([left, bottom, top])
        vals = np.concatenate([np.zeros(left.size + bottom.size), np.full(top.size, -0.02)])
        f_ramp = None
    else:
        dofs = np.concatenate([left, bottom])
        vals = np.zeros(dofs.size)
        f_ramp = macro.pressure_force("top", level * q_lim)
    dofs, first = np.unique(dofs, return_index=True)
    solver = Solver(macro, farm, Supports(dofs, vals[first]), f_ramp=f_ramp,
                    settings=SolverSettings(min_step=min_step))
    row = {"control": control, "level": level if control == "force" else None,
           "n_steps": n_steps, "error": None}
    try:
        for k in range(1, n_steps + 1):
            solver.advance(k / n_steps - solver.t)
    except SolverError as exc:
        row["error"] = str(exc)
    row.update(iterations=int(sum(solver.iterations)), cuts=solver.cuts,
               load_factor=solver.t, q_lim=q_lim,
               max_per_step=max(solver.iterations, default=0))
    return row


def newton_panel(quick):
    steps = [1, 2, 4, 8, 16] if quick else [1, 2, 4, 8, 16, 32, 64]
    rows = []
    for control, level in (("displacement", None), ("force", 0.9), ("force", 0.99),
                           ("force", 1.05)):
        for n in steps:
            rows.append(newton_case(control, n, level or 0.0))
            r = rows[-1]
            log(f"newton {control} {level} steps {n}: {r['iterations']} its, "
                f"{r['cuts']} cuts, t = {r['load_factor']:.4g}"
                + (" (SolverError)" if r["error"] else ""))
    return {"q_lim": rows[0]["q_lim"], "rows": rows}


# --------------------------------------------------------------------------- f. ADMM
def admm_panel(quick):
    from dem.contact.detection.admm import N_WARM, admm_contact
    from dem.shapes.kinds import BOX
    from dem.shapes.table import ShapeTable

    def geo_of(*halves):
        t = ShapeTable()
        for h in halves:
            t.add(_box_row(np.asarray(h, float)))
        return t.arrays()

    def quat(axis, angle):
        axis = np.asarray(axis, float) / np.linalg.norm(axis)
        return np.concatenate([[math.cos(angle / 2)], math.sin(angle / 2) * axis])

    def solve(geo, pos, rot, warm=None, max_iter=300, tol=1e-8):
        warm = np.zeros((1, N_WARM)) if warm is None else warm
        st, ov, *_, it = admm_contact(3, BOX, 0, 0, BOX, 1, 1, 0.0, 0.0, 0.0, pos, rot,
                                      np.zeros((2, 3)), geo, warm, 0, tol, max_iter)
        return int(st), float(ov), int(it)

    def stacked(h_a, h_b, tilt, depth, axis=(1.0, 0.0, 0.0)):
        """B above A (z), turned by ``tilt`` about ``axis``, overlapping by about
        ``depth`` [m] (face on face: exactly)."""
        rot = np.array([quat([1, 0, 0], 0.0), quat(axis, tilt)])
        rb = _rotation(rot[1])
        low = (np.abs(rb) @ np.asarray(h_b))[2]  # B's lowest point below its centre
        pos = np.array([[0.0, 0.0, 0.0], [0.05, -0.03, h_a[2] + low - depth]])
        return pos, rot

    out = {}
    tilts = [1e-1, 1e-2, 1e-3, 1e-4, 1e-6, 0.0] if quick else \
        [3e-1, 1e-1, 3e-2, 1e-2, 3e-3, 1e-3, 1e-4, 1e-5, 1e-6, 1e-8, 0.0]
    h = [1.0, 1.0, 0.3]
    geo = geo_of(h, h)
    rows = []
    for tilt in tilts:
        pos, rot = stacked(h, h, tilt, 0.01)
        st, ov, it = solve(geo, pos, rot)
        rows.append({"tilt": tilt, "status": st, "iterations": it, "overlap": ov})
    out["parallel"] = rows
    depths = [1e-4, 1e-3, 1e-2, 0.1, 0.3, 0.5] if quick else \
        [1e-5, 1e-4, 1e-3, 1e-2, 0.03, 0.1, 0.2, 0.3, 0.45, 0.55]
    rows = []
    for depth in depths:
        pos, rot = stacked(h, h, 0.3, depth, axis=(1.0, 2.0, 0.5))
        st, ov, it = solve(geo, pos, rot)
        rows.append({"depth": depth, "status": st, "iterations": it, "overlap": ov})
    out["deep"] = rows
    thick = [0.3, 0.1, 0.03, 0.01] if quick else [0.3, 0.1, 0.03, 0.01, 0.003, 0.001]
    rows = []
    for t in thick:  # two plates crossing at right angles, edge of B into A's face
        plate = [1.0, 1.0, t]
        g = geo_of(plate, plate)
        rot = np.array([quat([1, 0, 0], 0.0), quat([1, 0, 0], math.pi / 2 - 0.05)])
        depth = 0.3 * t
        low = (np.abs(_rotation(rot[1])) @ np.asarray(plate))[2]
        pos = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, t + low - depth]])
        st, ov, it = solve(g, pos, rot)
        rows.append({"thickness": t, "status": st, "iterations": it, "overlap": ov})
    out["thin"] = rows
    out["fallback"] = admm_fallback(solve, geo, stacked, h)
    out["simulation"] = admm_simulation()
    out["corner"] = admm_corner(quick)
    for k in ("parallel", "deep", "thin"):
        log(f"admm {k}: iterations {[r['iterations'] for r in out[k]]}, "
            f"status {[r['status'] for r in out[k]]}")
    return out


def _rotation(q):
    from dem.rotation import quat_to_matrix

    return quat_to_matrix(np.asarray(q, float))


def _box_row(h):
    """A ShapeTable row for a box of half extents ``h`` (3,)."""
    from dem.shapes import Box

    return Box(h).rows()


def admm_fallback(solve, geo, stacked, h):
    """A warm start left from a pose far away (stale), then caps on the iterations:
    the warm attempt fails within its budget (``min(cap, WARM_MAX_ITER)``), the cold
    restart succeeds (iterations > that budget); below the cold solve's own need,
    status 1."""
    from dem.contact.detection.admm import N_WARM, WARM_MAX_ITER

    pos_old, rot_old = stacked(h, h, 0.3, 0.05, axis=(1.0, 2.0, 0.5))
    pos_new, rot_new = stacked(h, h, 1.1, 0.02, axis=(-1.0, 0.3, 0.5))
    cold = solve(geo, pos_new, rot_new)[2]
    rows = []
    for cap in (300, 100, 30, 20, 15, 10, 8, 6, 4, 3, 2, 1):
        warm = np.zeros((1, N_WARM))
        solve(geo, pos_old, rot_old, warm=warm)
        st, _ov, it = solve(geo, pos_new, rot_new, warm=warm, max_iter=cap)
        rows.append({"cap": cap, "status": st, "iterations": it,
                     "cold_restart": bool(st == 0 and it > min(cap, WARM_MAX_ITER))})
    return {"cold_iterations": cold, "rows": rows}


def admm_simulation():
    """Two boxes colliding with ``detection="admm"``; the cap lowered until it fails."""
    from dem.shapes import Box

    rows = []
    for cap in (200, 20, 5, 2, 1):
        b = dem.Bodies.empty(3)
        b.add_shapes(Box([0.02, 0.015, 0.01]), [[0.0, 0.0, 0.0]], 1000.0,
                     rot=[[1.0, 0.0, 0.0, 0.0]], vel=[[0.5, 0.0, 0.0]],
                     ang_vel=[[0.0, 1.0, 2.0]])
        b.add_shapes(Box([0.02, 0.015, 0.01]), [[0.045, 0.005, 0.002]], 1000.0,
                     rot=[[0.9, 0.1, 0.3, 0.2]], vel=[[-0.5, 0.0, 0.0]],
                     ang_vel=[[1.0, 0.0, -1.0]])
        sim = dem.Simulation(b, dem.LinearSpring(kn=1e5), detection="admm",
                             admm_max_iter=cap, threads=1)
        sim.dt = 0.05 * sim.dt_crit
        row = {"cap": cap, "error": None, "max_iterations": 0}
        try:
            for _ in range(40):
                sim.run(20)
                iters = sim.shape_state.iters
                if len(iters):
                    row["max_iterations"] = max(row["max_iterations"], int(iters.max()))
        except dem.SimulationError as exc:
            row["error"] = str(exc)
        row["steps"] = sim.step
        rows.append(row)
        log(f"admm simulation cap {cap}: steps {sim.step}, max iterations "
            f"{row['max_iterations']}" + (f", error: {row['error']}" if row["error"] else ""))
    return rows


def admm_corner(quick):
    """Non-convex parts: a cube thrown into the inner corner of an L (a compound of
    two boxes, held still by its mass) hits both legs. Thrown diagonally, it goes as
    deep into one leg as into the other, and the lower leg's end edge then lies as
    deep below the cube's bottom face as below its side face: the summed SDFs have a
    crease at the solution. Thrown twice as fast sideways, no crease. Per impact
    speed: the deepest overlap (relative to the cube's half width), the most ADMM
    iterations of a contact over the impact at tolerances 1e-8 and 1e-6 (cap 300,
    warm-started from step to step), the steps whose warm solve stalled and was
    rescued by a cold restart (iterations > WARM_MAX_ITER, the warm attempt's budget,
    counted in all), or the error that stopped the run (warm and cold both failed)."""
    from dem.contact.detection.admm import WARM_MAX_ITER
    from dem.shapes import Box, Compound

    h = 0.02  # the cube's half width [m]
    legs = Compound([(Box([0.1, 0.03, 0.03]), [0.0, 0.0, 0.0]),
                     (Box([0.03, 0.03, 0.1]), [-0.07, 0.0, 0.13])])
    speeds = [0.01, 0.1, 1.0] if quick else [0.003, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0]
    rows = []
    for v in speeds:
        for side in (1.0, 2.0):  # speed towards the upright leg / towards the lower one
            row = {"speed": v, "side": side}
            for tol in (1e-8, 1e-6):
                b = dem.Bodies.empty(3)
                b.add_shapes(legs, [[0.0, 0.0, 0.0]], 1e9)  # an anchor
                b.add_shapes(Box([h] * 3), [[-0.04 + h + 1e-4, 0.0, 0.03 + h + 1e-4]],
                             1000.0, vel=[[-side * v, 0.0, -v]])
                sim = dem.Simulation(b, dem.LinearSpring(kn=1e5), detection="admm",
                                     admm_max_iter=300, admm_tol=tol, threads=1)
                res = {"error": None, "iterations": 0, "depth": 0.0, "contacts": 0,
                       "detections": 0, "cold_restarts": 0}
                try:
                    for _ in range(2000):
                        sim.run(1)
                        c = sim.contacts()
                        if len(c["i"]):
                            most = int(np.max(sim.shape_state.iters))
                            res["iterations"] = max(res["iterations"], most)
                            res["detections"] += 1
                            res["cold_restarts"] += int(most > WARM_MAX_ITER)
                            res["depth"] = max(res["depth"], float(c["overlap"].max()) / h)
                            res["contacts"] = max(res["contacts"], len(c["i"]))
                        elif res["contacts"]:
                            break  # bounced off
                except dem.SimulationError as exc:
                    res["error"] = str(exc).split(" at step")[0]
                res["steps"] = sim.step
                row[f"tol_{tol:g}"] = res
            rows.append(row)
            t8, t6 = row["tol_1e-08"], row["tol_1e-06"]
            log(f"admm corner speed {v:g} m/s side x{side:g}: depth {t8['depth']:.2g}, "
                f"contacts {t8['contacts']}; " + "; ".join(
                    f"tol {k[4:]} " + (t["error"] or f"iterations <= {t['iterations']}, "
                                       f"cold restarts {t['cold_restarts']} of "
                                       f"{t['detections']} steps in contact")
                    for k, t in (("tol_1e-8", t8), ("tol_1e-6", t6))))
    return rows


# --------------------------------------------------------------------------- chart
def visualize(res):
    """The six panels of :func:`main`'s results ``res`` (the JSON's content)."""
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    fig, axes = plt.subplots(2, 3, figsize=(15, 8.5))
    ax = axes[0, 0]
    for kind, d in res["spheres"].items():
        _energy_curve(ax, d["rows"], f"{kind} ({d['dim']}D, {d['n']})")
        ax.axvline(d["verlet_limit"], ls=":", color=ax.lines[-1].get_color(), lw=1)
        ax.axvline(d["refused_from"], ls="--", color=ax.lines[-1].get_color(), lw=0.8)
    _energy_axes(ax, "a. DEM spheres", extra=[
        Line2D([], [], ls=":", color="0.3", lw=1, label="lattice's Verlet limit 2/omega_max"),
        Line2D([], [], ls="--", color="0.3", lw=0.8, label="the engine refuses from")])
    ax = axes[0, 1]
    _energy_curve(ax, res["polyhedra"]["rows"], "polyhedra, edge on edge")
    _energy_axes(ax, "b. DEM polyhedra", res["polyhedra"].get("refused_from"))
    ax = axes[0, 2]
    _energy_curve(ax, res["peridynamics"]["rows"], "LPS plate (60 points)")
    _energy_axes(ax, "c. Peridynamics", 1.0)
    _rve_axes(axes[1, 0], res["rve"])
    _newton_axes(axes[1, 1], res["newton"])
    _admm_axes(axes[1, 2], res["admm"])
    fig.tight_layout()
    return fig


def _failed(ax, points, label, **style):
    """Failed runs as black crosses (``label`` names the error, for the legend)."""
    if points:
        ax.plot(*zip(*points, strict=True), "x", **({"color": "k", "ms": 10, "mew": 2}
                                                     | style), label=label)


def _rve_axes(ax, rv):
    """Panel d: relaxation steps against the strain increment, per damping; the
    legend above the cap, where nothing is drawn."""
    bad = []
    for c in sorted({r["damping"] for r in rv["rows"]}):
        rows = [r for r in rv["rows"] if r["damping"] == c]
        x = [r["strain"] for r in rows]
        y = [r["relax_steps"] if r["relax_steps"] is not None else rv["max_relax_steps"]
             for r in rows]
        ax.loglog(x, y, "o-", label=f"{c:g}")
        bad += [(xi, yi) for xi, yi, r in zip(x, y, rows, strict=True) if r["error"]]
    _failed(ax, bad, None)
    cap = rv["max_relax_steps"]
    ax.axhline(cap, color="k", lw=1, ls="--")
    ax.set_ylim(top=cap * 100.0)
    ax.set_xlabel("axial strain increment per call [-]")
    ax.set_ylabel("relaxation steps [-]")
    ax.set_title("d. RVE relaxation (x: RelaxationError at the cap)")
    ax.legend(fontsize=7, ncol=4, loc="upper center", title="Cundall damping [-]",
              title_fontsize=7)


def _newton_axes(ax, nw):
    """Panel e: Newton iterations of the whole load against the load step."""
    bad = []
    for key in sorted({(r["control"], r["level"] or 0.0) for r in nw["rows"]}):
        rows = [r for r in nw["rows"] if (r["control"], r["level"] or 0.0) == key]
        x = [1.0 / r["n_steps"] for r in rows]
        label = "displacement control" if key[0] == "displacement" else \
            f"pressure {key[1]:g} q_lim"
        ax.loglog(x, [max(r["iterations"], 1) for r in rows], "o-", label=label)
        bad += [(xi, max(r["iterations"], 1)) for xi, r in zip(x, rows, strict=True)
                if r["error"]]
    _failed(ax, bad, "SolverError at min_step")
    top = max(np.max(line.get_ydata()) for line in ax.lines)
    ax.set_ylim(top=top * 30.0)
    ax.set_xlabel("load step (fraction of the load) [-]")
    ax.set_ylabel("Newton iterations, whole load [-]")
    ax.set_title("e. Macro Newton")
    ax.legend(fontsize=7, ncol=2, loc="upper center")


def _admm_axes(ax, ad):
    """Panel f: ADMM iterations against the parameter of each family of poses."""
    ax.semilogx([max(r["tilt"], 1e-9) for r in ad["parallel"]],
                [r["iterations"] for r in ad["parallel"]], "o-",
                label="tilt [rad] of nearly parallel faces (0 at 1e-9)")
    ax.semilogx([r["depth"] for r in ad["deep"]], [r["iterations"] for r in ad["deep"]],
                "s-", label="penetration depth / half width [-]")
    ax.semilogx([r["thickness"] for r in ad["thin"]],
                [r["iterations"] for r in ad["thin"]], "^-",
                label="plate thickness / half width [-]")
    corner = [r for r in ad.get("corner", []) if r["side"] == 1.0]
    cap = 300
    if corner:  # failures drawn at the cap
        ok = [r for r in corner if not r["tol_1e-08"]["error"]]
        ax.semilogx([r["tol_1e-08"]["depth"] for r in ok],
                    [r["tol_1e-08"]["iterations"] for r in ok], "D-",
                    label="cube into an L's corner (non-convex): depth / half width [-],"
                    "\nmost iterations of a run")
        bad = [r["tol_1e-06"]["depth"] for r in corner if r["tol_1e-08"]["error"]]
        _failed(ax, [(b, cap) for b in bad], "no convergence (drawn at 300)")
    fb = ad["fallback"]
    ax.axhline(fb["cold_iterations"], color="k", lw=1, ls=":",
               label="cold solve of the fallback pose")
    ax.set_yscale("log")
    top = max(np.max(line.get_ydata()) for line in ax.lines)
    ax.set_ylim(top=top * 300.0)
    ax.set_xlabel("parameter of the poses (see the legend) [rad] or [-]")
    ax.set_ylabel("ADMM iterations to 1e-8 [-]")
    ax.set_title("f. ADMM detection, boxes")
    ax.legend(fontsize=7, loc="upper center")


def _energy_curve(ax, rows, label):
    x = [r["factor"] for r in rows]
    y = [min(r["energy_error"], 1e3) if r["energy_error"] is not None else 1e3
         for r in rows]
    line, = ax.loglog(x, [max(v, 1e-12) for v in y], "o-", label=label, ms=4)
    bad = [(xi, max(yi, 1e-12)) for xi, yi, r in zip(x, y, rows, strict=True)
           if r["error"]]
    _failed(ax, bad, None, color=line.get_color(), ms=9)


def _energy_axes(ax, title, refused=None, extra=()):
    """Axes of panels a-c: the failure line, the refusal line, the legend (with a
    cross for a SimulationError) above the curves."""
    from matplotlib.lines import Line2D

    ax.axhline(FAIL, color="k", lw=1, ls="--")
    handles = [line for line in ax.lines if not line.get_label().startswith("_")]
    handles += [Line2D([], [], ls="--", color="k", lw=1, label="failure: error 1"),
                Line2D([], [], ls="", marker="x", color="0.3", mew=2,
                       label="SimulationError")]
    if refused is not None:
        ax.axvline(refused, color="r", lw=1)
        handles.append(Line2D([], [], color="r", lw=1,
                              label="refused above (without allow_unstable_dt)"))
    ax.set_xlabel("dt / dt_crit [-]")
    ax.set_ylabel("energy error max |E - E0| / K0 [-]")
    ax.set_title(title)
    bottom, top = ax.get_ylim()
    ax.set_ylim(bottom, top * 1e4)  # room for the legend above the curves
    handles += extra
    ax.legend(handles=handles, fontsize=7, ncol=2 if len(handles) > 4 else 1,
              loc="upper left")


# --------------------------------------------------------------------------- main
def log(msg):
    print(msg, flush=True)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="coarse grids, smaller sweeps")
    p.add_argument("--only", nargs="*", default=None,
                   help="panels to run (spheres polyhedra peridynamics rve newton admm)")
    p.add_argument("--figure", action="store_true",
                   help="redraw the chart from the results' JSON (runs nothing)")
    args = p.parse_args(argv)
    if args.figure:
        name = OUT.relative_to(REPO) if OUT.is_relative_to(REPO) else OUT
        try:
            res = json.loads(OUT.read_text())
        except FileNotFoundError:
            p.exit(2, f"error: {name}: not found (run the sweep first)\n")
        except (OSError, ValueError) as err:
            p.exit(2, f"error: {name}: cannot read the results ({err})\n")
        missing = [k for k in PANELS if k not in res]
        if missing:
            p.exit(2, f"error: {name}: no results for the panels {', '.join(missing)} "
                   f"(run them with --only)\n")
        PNG.parent.mkdir(parents=True, exist_ok=True)
        visualize(res).savefig(PNG, dpi=110)
        log(f"wrote {PNG}")
        return
    # past the limit load the tangent is singular: expected, the solver reports it
    warnings.filterwarnings("ignore", message="Matrix is exactly singular")
    grid = QUICK_GRID if args.quick else FULL_GRID
    panels = {
        "spheres": lambda: sphere_panel(grid),
        "polyhedra": lambda: polyhedra_panel(grid + [2.0, 3.0, 5.0]),
        "peridynamics": lambda: pd_panel(grid),
        "rve": lambda: rve_panel(args.quick),
        "newton": lambda: newton_panel(args.quick),
        "admm": lambda: admm_panel(args.quick),
    }
    res = json.loads(OUT.read_text()) if args.only and OUT.exists() else {}
    res["quick"] = args.quick
    for name, fn in panels.items():
        if args.only and name not in args.only:
            continue
        t0 = time.perf_counter()
        res[name] = fn()
        log(f"{name}: {time.perf_counter() - t0:.1f} s")
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(res, indent=1))
    if all(k in res for k in PANELS):
        PNG.parent.mkdir(parents=True, exist_ok=True)
        visualize(res).savefig(PNG, dpi=110)
        log(f"wrote {OUT} and {PNG}")
    else:
        log(f"wrote {OUT} (the chart needs every panel)")


if __name__ == "__main__":
    main()
