"""The periodic RVE against YADE: the same packing, law and test in both engines.

Cross-validation. The 400-disk packings of ``benchmarks/rve_call.py`` (radii uniform in
0.8-1.2 mm, linear springs kn = 1e8 N/m, kt = 5e7 N/m, friction 0.5, density 2650
kg/m^3, consolidated frictionless to 100 kPa, then at friction 0.5), one per seed of
``SEEDS``, and the 1,000-sphere ones in 3D, are exported -- positions, radii, masses,
moments of inertia, cell -- and both engines start from each with fresh contacts (no
tangential history). Each runs the drained biaxial test of
``hmm rve``: isotropic consolidation at 100 kPa, then axial compression in increments
of 1e-3, each imposed in steps of at most 1e-5 strain and relaxed (unbalanced-force
ratio below 1e-3) while a servo holds the lateral stress at 100 kPa. Our side is
:func:`hmm.experiment.compress`; the YADE side is a script this file writes (our own
text) that drives YADE's periodic cell through ``O.cell.velGrad`` and ``O.step()``
with the same algorithm (same chunk of 50 steps between checks, same servo gain from
the contact-stiffness tangent, same tolerances). Measured: the largest difference of
the deviatoric stress q up to our peak of q, relative to that peak
(``max_rel_deviation_2d``, the largest over the packings; the target is 3 %), and the
same for p, q/p and the volumetric strain. Both engines start from bit-identical
contact forces (checked: the stress of the exported state agrees to 1e-9); past the
first contact slips the two
trajectories part as any two chaotic runs do, and the number says how far.

Matching the physics:

* YADE's ``Ip2_FrictMat_FrictMat_FrictPhys`` gives ``kn = 2 E1 r1 E2 r2 / (E1 r1 +
  E2 r2)`` and ``ks = 2 E1 r1 v1 E2 r2 v2 / (E1 r1 v1 + E2 r2 v2)``: every particle
  gets its own ``FrictMat`` with ``young = kn / r`` and ``poisson = kt / kn``, so that
  every contact has exactly ``kn`` and ``kt`` (checked on the contacts);
  ``frictionAngle = atan(mu)``; no viscous damping in either engine;
* 2D: YADE spheres in one plane of a periodic cell of thickness ``Lz`` (> 2 diameters,
  never strained), with ``blockedDOFs = "zXY"``; their masses and moments of inertia
  are set to our disks' (per unit thickness). YADE's stress is per volume ``A Lz``,
  ours per area: YADE's is multiplied by ``Lz``, the same forces over the same area;
* Cundall local damping 0.5 in both (``NewtonIntegrator(damping=0.5)``); the same
  time step; no gravity.

Performance. One Gauss-point call -- from a consolidated state, an axial strain
increment of 1e-4 imposed in steps of 1e-5, relaxation to an unbalanced-force ratio of
1e-3, then stress and contact tangent -- timed in both engines on the same packing,
rounds of ours and YADE's alternating. YADE's chunks of steps run as a loop of
``O.step()`` (``speedup_rve_call``, the strongest driver of YADE from Python) and as
blocking ``O.run(n, True)`` calls, the way FEMxDEM's RVEs are stepped
(``speedup_rve_call_blocking``: YADE's call as FEMxDEM makes it, its polling floor
included). Plain stepping of the same RVE, particle-steps per second of our loop over
YADE's ``O.step()`` loop: ``speedup_stepping``. YADE runs on one thread (``-j 1``),
ours too. Our call is ``RVE.apply_strain(deps, tangent=True)``, the stress and the
tangent from one measuring pass, as a Gauss point asks (before 2026-12-06 it was timed
as ``apply_strain``, ``stress()`` and ``tangent()``: three passes). With ``DIMS="2 3"``
the 1,000-sphere RVE is timed too: the same keys ending in ``_3d``.

usage::

    python benchmarks/rve_vs_yade.py   # writes benchmarks/results/rve_vs_yade.json
                                       # and docs/figures/rve_vs_yade.png

environment: DIMS ("2"; "2 3" adds the 1,000-sphere triaxial test), SEEDS ("1 2 3":
the packings compared, each its own seed), AXIAL (0.06,
total axial strain), ROUNDS (3) and CALLS (5) of the timing, PART ("all"; "curves" or
"timing" runs one half and keeps the other's entries of the JSON), YADE (the
executable, default ``yade``). Without YADE the peer is skipped and the JSON says so.
"""

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C

OUT = C.RESULTS / "rve_vs_yade.json"
FIGURE = C.REPO / "docs" / "figures" / "rve_vs_yade.png"
SCRATCH = C.WORK / "rve_vs_yade"

P0 = 1.0e5  # [Pa] consolidation and confining pressure
#: the packings (as benchmarks/rve_call.py) and the test settings of both engines
SETUP = {
    2: {"n": 400, "kn": 1e8, "kt": 5e7, "mu": 0.5},
    3: {"n": 1000, "kn": 1e5, "kt": 5e4, "mu": 0.5},
}
RADIUS = (0.8e-3, 1.2e-3)
DENSITY = 2650.0
TEST = {"damping": 0.5, "tol": 1e-3, "stress_tol": 1e-3, "max_step_strain": 1e-5,
        "max_relax_steps": 200_000, "check_every": 50, "increment": 1e-3}
CALL_STRAIN = 1e-4  # axial strain increment of one Gauss-point call
STEPPING_STEPS = 2000


# --------------------------------------------------------------------------- our side
def packing(dim, seed=1):
    """The consolidated packing of ``dim`` and ``seed`` (made once, then read from the
    scratch dir)."""
    import dem
    from dem import rve

    path = SCRATCH / (f"packing_{dim}d.h5" if seed == 1 else f"packing_{dim}d_s{seed}.h5")
    s = SETUP[dim]
    if path.exists():
        return rve.RVE.load_file(path)
    law = dem.LinearSpring(kn=s["kn"], kt=s["kt"], mu=s["mu"])
    r = rve.generate(dim, s["n"], RADIUS, law, p0=P0, friction=0.0, seed=seed,
                     density=DENSITY)
    path.parent.mkdir(parents=True, exist_ok=True)
    r.save(path, p0=P0)
    return r


def export(dim, seed=1):
    """The packing at the working friction, as plain lists for both engines."""
    import numpy as np

    r = packing(dim, seed)
    r.consolidate(P0)  # at the working friction, as hmm.experiment.compress does
    b, cell = r.bodies, r.cell
    pos = b.pos.copy()
    cell.wrap(pos, np.arange(b.n))
    s = SETUP[dim]
    return {"dim": dim, "pos": pos.tolist(), "radius": b.radius.tolist(),
            "mass": b.mass.tolist(), "inertia": b.inertia[:, -1].tolist(),
            "h": cell.h.tolist(), "dt": r.sim.dt, "kn": s["kn"], "kt": s["kt"],
            "mu": s["mu"], "p0": P0, "thickness": 6.0 * max(RADIUS), **TEST}


def fresh_rve(ex):
    """Our RVE from an export: fresh contacts, the exported time step."""
    import numpy as np

    import dem
    from dem import rve
    from dem.boundary import PeriodicCell

    bodies = dem.Bodies.spheres(np.array(ex["pos"]), radius=np.array(ex["radius"]),
                                density=DENSITY)
    if not np.allclose(bodies.mass, ex["mass"], rtol=1e-12):
        raise RuntimeError("masses of the rebuilt packing differ from the export")
    law = dem.LinearSpring(kn=ex["kn"], kt=ex["kt"], mu=ex["mu"])
    return rve.RVE(bodies, law, PeriodicCell(np.array(ex["h"])), damping=ex["damping"],
                   dt=ex["dt"], tol=ex["tol"], stress_tol=ex["stress_tol"],
                   max_step_strain=ex["max_step_strain"],
                   max_relax_steps=ex["max_relax_steps"], check_every=ex["check_every"])


def ours_compression(ex, axial):
    from hmm.experiment import compress, validate_config

    dim = ex["dim"]
    cfg = validate_config({
        "packing": {"dim": dim, "count": len(ex["radius"]), "radius": list(RADIUS),
                    "p0": P0},
        "contact": {"law": "linear", "kn": ex["kn"], "kt": ex["kt"], "mu": ex["mu"]},
        "test": {"axial_strain": axial, "increment": ex["increment"],
                 "damping": ex["damping"], "tol": ex["tol"],
                 "stress_tol": ex["stress_tol"], "max_step_strain": ex["max_step_strain"],
                 "max_relax_steps": ex["max_relax_steps"]}}, "rve_vs_yade.toml")
    t0 = time.perf_counter()
    res = compress(cfg, packing=(fresh_rve(ex), P0, False))
    c = res.curves
    return {"axial_strain": c["axial_strain"].tolist(),
            "volumetric_strain": c["volumetric_strain"].tolist(),
            "p": c["p"].tolist(), "q": c["q"].tolist(),
            "relax_steps": c["relax_steps"].tolist(),
            "n_contacts": c["n_contacts"].tolist(),
            "wall_time": time.perf_counter() - t0}


def ours_timing(ex, calls):
    """Gauss-point calls and plain stepping of our RVE (as benchmarks/rve_call.py)."""
    import numpy as np

    r = fresh_rve(ex)
    r.consolidate(P0)
    snap = r.snapshot()
    d = ex["dim"]
    deps = np.zeros((d, d))
    deps[-1, -1] = -CALL_STRAIN
    times, steps = [], []
    for _ in range(calls + 1):  # the first call is a warm-up
        r.restore(snap)
        s0 = r.sim.step
        t0 = time.perf_counter()
        r.apply_strain(deps, tangent=True)  # stress and tangent, as a Gauss point asks
        times.append(time.perf_counter() - t0)
        steps.append(r.sim.step - s0)
    r.restore(snap)
    r.sim.run(100, progress=False)
    t0 = time.perf_counter()
    r.sim.run(STEPPING_STEPS, progress=False)
    t_run = time.perf_counter() - t0
    return {"call_times": times[1:], "steps_per_call": steps[1:],
            "particle_steps_per_s": len(ex["radius"]) * STEPPING_STEPS / t_run}


# --------------------------------------------------------------------------- YADE side
#: the script YADE runs: builds the scene of an export and drives it (see the module)
YADE_SCRIPT = r'''
import json, math, os, time
import numpy as np

ex = json.load(open(os.environ["RVE_YADE_IN"]))
D, DT, MODE = ex["dim"], ex["dt"], os.environ["RVE_YADE_MODE"]
CHECK, TOL, STOL, SHEAR_TOL = ex["check_every"], ex["tol"], ex["stress_tol"], 1e-2
LZ = ex["thickness"]

O.periodic = True
h3 = np.eye(3) * LZ
h3[:D, :D] = np.array(ex["h"])
O.cell.hSize = Matrix3(*h3.ravel().tolist())
for x, r, m, inertia in zip(ex["pos"], ex["radius"], ex["mass"], ex["inertia"]):
    mat = O.materials.append(FrictMat(young=ex["kn"] / r, poisson=ex["kt"] / ex["kn"],
                                      frictionAngle=math.atan(ex["mu"]), density=1.0))
    c = list(x) + ([0.5 * LZ] if D == 2 else [])
    b = utils.sphere(Vector3(*c), r, material=mat)
    b.state.mass = m
    b.state.inertia = Vector3(inertia, inertia, inertia)
    if D == 2:
        b.state.blockedDOFs = "zXY"
    O.bodies.append(b)
O.engines = [
    ForceResetter(),
    InsertionSortCollider([Bo1_Sphere_Aabb()]),
    InteractionLoop([Ig2_Sphere_Sphere_ScGeom()], [Ip2_FrictMat_FrictMat_FrictPhys()],
                    [Law2_ScGeom_FrictPhys_CundallStrack()]),
    NewtonIntegrator(damping=ex["damping"], gravity=(0, 0, 0)),
]
O.dt = 0.0  # a step of zero length makes the contacts of the initial state (a prime)
O.step()
O.dt = DT


def cell_matrix():
    return np.array([[O.cell.hSize[i, j] for j in range(3)] for i in range(3)])


def set_velgrad(lg):
    m = np.zeros((3, 3))
    m[:D, :D] = lg
    O.cell.velGrad = Matrix3(*m.ravel().tolist())


def contacts():
    """kn, ks, normals (m, D) and branch vectors (m, D) of the real contacts."""
    rows = []
    hs = O.cell.hSize
    for i in O.interactions:
        if not i.isReal:
            continue
        l = O.bodies[i.id2].state.pos + hs * i.cellDist - O.bodies[i.id1].state.pos
        n = i.geom.normal
        rows.append((i.phys.kn, i.phys.ks, n[0], n[1], n[2], l[0], l[1], l[2]))
    a = np.array(rows).reshape(-1, 8)
    return a[:, 0], a[:, 1], a[:, 2:2 + D], a[:, 5:5 + D]


def volume():
    h = cell_matrix()
    return float(np.linalg.det(h[:D, :D]))


def stress():
    """Love-Weber stress (D, D) [Pa], tension positive; 2D: per unit thickness."""
    s = utils.getStress()
    s = np.array([[s[i, j] for j in range(D)] for i in range(D)])
    return s * LZ if D == 2 else s


def tangent():
    kn, ks, n, l = contacts()
    eye = np.eye(D)
    cn = np.einsum("c,ci,cj,ck,cl->ijkl", kn, n, l, n, l)
    proj = eye[None] - np.einsum("ci,ck->cik", n, n)
    ct = np.einsum("c,cik,cj,cl->ijkl", ks, proj, l, l)
    return (cn + ct) / volume()


def response(with_tangent):
    out = {"stress": stress(), "unbalanced": utils.unbalancedForce()}
    if with_tangent:
        out["tangent"] = tangent()
    return out


def drive(deps, target, mask, max_step_strain, blocking=False):
    """Strain on the components outside ``mask`` (diagonal ``deps``), a servo on those
    in it, then relaxation: the algorithm of dem.rve.RVE.load, step for step. Each
    chunk of steps is a loop of ``O.step()``, or with ``blocking`` one ``O.run(n,
    True)``, the call FEMxDEM's RVEs make."""
    n_load = int(math.ceil(np.abs(deps).max() / max_step_strain)) if deps.any() else 0
    l_load = np.zeros((D, D))
    if n_load:
        l_load = np.diag((1.0 + np.diag(deps)) ** (1.0 / n_load) - 1.0) / DT
    rate_max = max_step_strain / DT
    tau = 4.0 * CHECK * DT
    steps = done = 0
    servoed = bool(mask.any())
    r = response(servoed)
    while True:
        ok_all = True
        lg = np.zeros((D, D))
        if servoed:
            c, s = r["tangent"], r["stress"]
            scale = max(np.abs(np.diag(target)).max(), abs(np.trace(s)) / D, 1e-300)
            for a, b in zip(*np.nonzero(np.triu(mask))):
                err = target[a, b] - s[a, b]
                if a == b and target[a, b] != 0.0:
                    ok = abs(err) <= STOL * abs(target[a, b])
                else:
                    ok = abs(err) <= SHEAR_TOL * scale
                ok_all = ok_all and ok
                m = c[a, b, a, b] * (1.0 if a == b else 2.0)
                rate = err / (m * tau) if m > 0.0 else math.copysign(rate_max, err)
                lg[a, b] = lg[b, a] = max(-rate_max, min(rate_max, rate))
        n_chunk = CHECK
        if done < n_load:
            n_chunk = min(n_chunk, n_load - done)
            lg += l_load
        elif ok_all and r["unbalanced"] < TOL:
            break
        if steps - n_load >= ex["max_relax_steps"]:
            raise RuntimeError("YADE cell did not relax")
        set_velgrad(lg)
        if blocking:
            O.run(n_chunk, True)
        else:
            for _ in range(n_chunk):
                O.step()
        set_velgrad(np.zeros((D, D)))
        steps += n_chunk
        if done < n_load:
            done += n_chunk
        r = response(servoed)
    return r, steps


def consolidate():
    full = np.ones((D, D), bool)
    return drive(np.zeros((D, D)), -ex["p0"] * np.eye(D), full, 1e-4)


from yade import config as yade_config
result = {"yade_version": getattr(yade_config, "version", None)}
t0 = time.perf_counter()
consolidate()
result["consolidation_time"] = time.perf_counter() - t0
kn, ks, _, _ = contacts()
result["contact_kn"] = [float(kn.min()), float(kn.max())]
result["contact_ks"] = [float(ks.min()), float(ks.max())]
axial = D - 1
lateral_mask = np.diag(np.arange(D) != axial)
if MODE == "compress":
    f0_inv = np.linalg.inv(cell_matrix()[:D, :D])
    rows = []

    def record(s, steps):
        f = cell_matrix()[:D, :D] @ f0_inv
        ev = np.sort(np.linalg.eigvalsh(-s))
        if D == 2:
            p, q = 0.5 * (ev[1] + ev[0]), 0.5 * (ev[1] - ev[0])
        else:
            p = ev.mean()
            q = math.sqrt(1.5 * float(((ev - p) ** 2).sum()))
        rows.append({"axial_strain": 1.0 - f[axial, axial],
                     "volumetric_strain": 1.0 - np.linalg.det(f), "p": p, "q": q,
                     "relax_steps": steps, "n_contacts": len(contacts()[0])})

    record(stress(), 0)
    n_inc = int(math.ceil(float(os.environ["RVE_YADE_AXIAL"]) / ex["increment"] - 1e-9))
    t0 = time.perf_counter()
    for k in range(1, n_inc + 1):
        target = k * ex["increment"]
        f = cell_matrix()[:D, :D] @ f0_inv
        deps = np.zeros((D, D))
        deps[axial, axial] = (1.0 - target) / f[axial, axial] - 1.0
        r, steps = drive(deps, -ex["p0"] * np.eye(D), lateral_mask, ex["max_step_strain"])
        record(r["stress"], steps)
    result["wall_time"] = time.perf_counter() - t0
    result["curves"] = {k: [float(row[k]) for row in rows] for k in rows[0]}
else:
    calls = int(os.environ["RVE_YADE_CALLS"])
    O.saveTmp("base")
    deps = np.zeros((D, D))
    deps[axial, axial] = -float(os.environ["RVE_YADE_STRAIN"])
    times, times_no_tangent, steps = [], [], []
    for _ in range(calls + 1):
        O.loadTmp("base")
        t0 = time.perf_counter()
        r, n = drive(deps, np.zeros((D, D)), np.zeros((D, D), bool), ex["max_step_strain"])
        t1 = time.perf_counter()
        tangent()
        t2 = time.perf_counter()
        times.append(t2 - t0)
        times_no_tangent.append(t1 - t0)
        steps.append(n)
    result.update(call_times=times[1:], call_times_no_tangent=times_no_tangent[1:],
                  steps_per_call=steps[1:])
    blocking = []
    for _ in range(calls + 1):
        O.loadTmp("base")
        t0 = time.perf_counter()
        drive(deps, np.zeros((D, D)), np.zeros((D, D), bool), ex["max_step_strain"],
              blocking=True)
        tangent()
        blocking.append(time.perf_counter() - t0)
    result["call_times_blocking"] = blocking[1:]
    n_steps = int(os.environ["RVE_YADE_STEPS"])
    O.loadTmp("base")
    for _ in range(100):
        O.step()
    t0 = time.perf_counter()
    for _ in range(n_steps):
        O.step()
    result["particle_steps_per_s"] = len(O.bodies) * n_steps / (time.perf_counter() - t0)
    O.loadTmp("base")
    O.run(100, True)
    t0 = time.perf_counter()
    O.run(n_steps, True)
    result["particle_steps_per_s_run"] = len(O.bodies) * n_steps / (time.perf_counter() - t0)
with open(os.environ["RVE_YADE_OUT"], "w") as fh:
    json.dump(result, fh)
'''


def yade_executable():
    exe = os.environ.get("YADE", "yade")
    return shutil.which(exe)


def run_yade(ex, mode, timeout=3600, **env):
    """Run the YADE script on an export in a temporary directory; its result dict."""
    exe = yade_executable()
    with tempfile.TemporaryDirectory(prefix="rve_yade_") as tmp:
        tmp = Path(tmp)
        (tmp / "export.json").write_text(json.dumps(ex))
        (tmp / "drive.py").write_text(YADE_SCRIPT)
        e = dict(os.environ, OMP_NUM_THREADS="1", RVE_YADE_IN=str(tmp / "export.json"),
                 RVE_YADE_OUT=str(tmp / "out.json"), RVE_YADE_MODE=mode)
        e.pop("DISPLAY", None)
        e.update({f"RVE_YADE_{k.upper()}": str(v) for k, v in env.items()})
        t0 = time.perf_counter()
        p = subprocess.run([exe, "-j", "1", "-n", "-x", "drive.py"], cwd=tmp, env=e,
                           stdin=subprocess.DEVNULL, capture_output=True, text=True,
                           timeout=timeout, check=False)
        if not (tmp / "out.json").exists():
            tail = (p.stderr or p.stdout).strip().splitlines()[-10:]
            raise RuntimeError(f"YADE failed (rc={p.returncode}): " + " | ".join(tail))
        out = json.loads((tmp / "out.json").read_text())
        out["process_time"] = time.perf_counter() - t0
        return out


# --------------------------------------------------------------------------- comparison
def deviation(ours, peer):
    """Largest |q_yade - q_ours| (and |p|, |eps_v| differences) up to our peak of q,
    relative to that peak (strains: absolute)."""
    import numpy as np

    q1, q2 = np.array(ours["q"]), np.array(peer["q"])
    n = min(q1.size, q2.size)
    k = int(np.argmax(q1[:n]))
    peak = float(q1[k])
    upto = slice(0, k + 1)
    r1 = q1[:n] / np.array(ours["p"][:n])
    r2 = q2[:n] / np.array(peer["p"][:n])
    ev1, ev2 = np.array(ours["volumetric_strain"][:n]), np.array(peer["volumetric_strain"][:n])
    rel = np.abs(q2[:n] - q1[:n]) / peak
    return {"peak_q": peak, "peak_axial_strain": float(ours["axial_strain"][k]),
            "peak_q_yade": float(q2[:n].max()),
            "peak_axial_strain_yade": float(peer["axial_strain"][int(np.argmax(q2[:n]))]),
            "max_rel_deviation": float(rel[upto].max()),
            "max_rel_deviation_at": float(ours["axial_strain"][int(np.argmax(rel[upto]))]),
            "max_rel_deviation_to_1pc": float(rel[np.array(ours["axial_strain"][:n]) <=
                                                  0.01 + 1e-12].max()),
            "max_rel_deviation_p": float((np.abs(np.array(peer["p"][:n]) -
                                                 np.array(ours["p"][:n])) /
                                          P0)[upto].max()),
            "max_abs_deviation_stress_ratio": float(np.abs(r2 - r1)[upto].max()),
            "max_abs_deviation_volumetric_strain": float(np.abs(ev2 - ev1)[upto].max())}


def visualize(data):
    """One row per dimension: q and volumetric strain, every packing (colour), ours
    (solid) and YADE's (dashed)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    rows = [c for c in data["comparison"] if "ours" in c]
    dims = sorted({c["dim"] for c in rows})
    fig = Figure(figsize=(9.0, 3.4 * max(1, len(dims))), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(max(1, len(dims)), 2, squeeze=False)
    for (ax1, ax2), dim in zip(axes, dims, strict=False):
        mine = [c for c in rows if c["dim"] == dim]
        devs = [c["deviation"]["max_rel_deviation"] for c in mine if "deviation" in c]
        for k, c in enumerate(mine):
            for key, ls in (("ours", "-"), ("yade", "--")):
                if key not in c:
                    continue
                ea = [100.0 * x for x in c[key]["axial_strain"]]
                name = f"{'ours' if key == 'ours' else 'YADE'}, packing {c.get('seed', 1)}"
                ax1.plot(ea, [q / 1e3 for q in c[key]["q"]], ls, color=f"C{k}", label=name)
                ax2.plot(ea, [100.0 * x for x in c[key]["volumetric_strain"]], ls,
                         color=f"C{k}")
        label = {2: "400 disks, biaxial", 3: "1,000 spheres, triaxial"}[dim]
        title = label if not devs else (
            f"{label}: |Δq| to the peak ≤ {100 * max(devs):.1f} % of q_peak")
        ax1.set(xlabel="axial strain [%]", ylabel="q [kPa]", title=title)
        ax2.set(xlabel="axial strain [%]", ylabel="volumetric strain [%] (+ contraction)")
        ax2.axhline(0.0, color="0.6", lw=0.8)
        ax1.legend(loc="lower right", fontsize=7)
    return fig


def _joined(runs, key):
    """The lists ``run[key]`` of all runs, end to end."""
    return [x for r in runs for x in r[key]]


def curves(data, dims, axial, exe, seeds):
    """The drained tests of both engines and their deviation, into ``data``: one row
    per dimension and packing seed; ``max_rel_deviation_<d>d`` is the largest over the
    seeds (the figure shows the first seed)."""
    data["comparison"] = []
    for dim in dims:
        worst = None
        for seed in seeds:
            t0 = time.perf_counter()
            ex = export(dim, seed)
            row = {"dim": dim, "seed": seed, "particles": len(ex["radius"]),
                   "dt": ex["dt"], "yade_thickness": ex["thickness"]}
            print(f"{dim}D packing {seed} ready ({time.perf_counter() - t0:.0f} s)",
                  flush=True)
            row["ours"] = ours_compression(ex, axial)
            print(f"{dim}D ours: {row['ours']['wall_time']:.0f} s", flush=True)
            if exe is not None:
                y = run_yade(ex, "compress", axial=axial)
                row["yade"] = y.pop("curves")
                row["yade"]["wall_time"] = y["wall_time"]
                row["yade_info"] = y
                row["deviation"] = deviation(row["ours"], row["yade"])
                dev = row["deviation"]["max_rel_deviation"]
                worst = dev if worst is None else max(worst, dev)
                print(f"{dim}D YADE: {y['wall_time']:.0f} s; max |dq| / q_peak up to "
                      f"the peak = {dev:.4f}", flush=True)
            data["comparison"].append(row)
        data[f"max_rel_deviation_{dim}d"] = worst
    for dim in (2, 3):
        if dim not in dims:
            data[f"max_rel_deviation_{dim}d"] = None


def timing(data, rounds, calls, exe, dims):
    """Gauss-point calls and stepping of the 2D RVE (and the 3D one with ``dims``),
    rounds of ours and YADE's alternating, into ``data``: keys ending in ``_3d`` are the
    3D RVE's."""
    for dim in dims:
        _timing(data, rounds, calls, exe, dim, "" if dim == 2 else "_3d")


def _timing(data, rounds, calls, exe, dim, tag):
    ex = export(dim)
    ours_runs, yade_runs = [], []
    for k in range(rounds):
        ours_runs.append(C.run_worker(__file__, ["timing", calls, dim], threads=1))
        if exe is not None:
            yade_runs.append(run_yade(ex, "timing", calls=calls, strain=CALL_STRAIN,
                                      steps=STEPPING_STEPS))
        print(f"{dim}D timing round {k + 1}/{rounds} done", flush=True)
    bad = [r["error"] for r in ours_runs if not r.get("ok")]
    if bad:
        raise RuntimeError("our timing worker failed: " + bad[0])
    t = {"ours_call_time": C.median(_joined(ours_runs, "call_times")),
         "ours_steps_per_call": C.median(_joined(ours_runs, "steps_per_call")),
         "ours_particle_steps_per_s": C.median([r["particle_steps_per_s"]
                                                for r in ours_runs]),
         "ours_runs": ours_runs}
    if yade_runs:
        t.update(
            yade_call_time=C.median(_joined(yade_runs, "call_times")),
            yade_call_time_no_tangent=C.median(
                _joined(yade_runs, "call_times_no_tangent")),
            yade_call_time_blocking=C.median(_joined(yade_runs, "call_times_blocking")),
            yade_steps_per_call=C.median(_joined(yade_runs, "steps_per_call")),
            yade_particle_steps_per_s=C.median([r["particle_steps_per_s"]
                                                for r in yade_runs]),
            yade_particle_steps_per_s_run=C.median([r["particle_steps_per_s_run"]
                                                    for r in yade_runs]),
            yade_runs=yade_runs)
        call = data["speedup_rve_call" + tag] = t["yade_call_time"] / t["ours_call_time"]
        blocking = data["speedup_rve_call_blocking" + tag] = (t["yade_call_time_blocking"]
                                                              / t["ours_call_time"])
        stepping = data["speedup_stepping" + tag] = (t["ours_particle_steps_per_s"]
                                                     / t["yade_particle_steps_per_s"])
        print(f"{dim}D Gauss-point call: ours {1e3 * t['ours_call_time']:.1f} ms, YADE "
              f"{1e3 * t['yade_call_time']:.1f} ms (speedup {call:.2f}), with blocking "
              f"O.run {1e3 * t['yade_call_time_blocking']:.1f} ms (speedup {blocking:.2f});"
              f" stepping ours {t['ours_particle_steps_per_s'] / 1e6:.2f}, YADE "
              f"{t['yade_particle_steps_per_s'] / 1e6:.2f} M particle-steps/s (speedup "
              f"{stepping:.2f})")
    else:
        data["speedup_rve_call" + tag] = data["speedup_stepping" + tag] = None
        data["speedup_rve_call_blocking" + tag] = None
    data["timing" + tag] = t


def main():
    """``PART``: "all" (default), "curves" or "timing"; a part alone replaces its own
    entries of an existing JSON and keeps the other part's (each entry says when and
    at which revision it was measured)."""
    dims = [int(x) for x in C.env_list("DIMS", "2")]
    seeds = [int(x) for x in C.env_list("SEEDS", "1 2 3")]
    axial = float(os.environ.get("AXIAL", "0.06"))
    rounds, calls = C.env_int("ROUNDS", 3), C.env_int("CALLS", 5)
    part = os.environ.get("PART", "all")
    if part not in ("all", "curves", "timing"):
        raise SystemExit(f"PART must be all, curves or timing, got {part!r}")
    exe = yade_executable()
    data = {}
    if part != "all" and OUT.exists():
        data = json.loads(OUT.read_text())
    stamp = {"date": C.now(), "revision": C.git_revision(), "loadavg": C.loadavg()}
    data.update({"benchmark": "rve_vs_yade", "date": stamp["date"],
                 "machine": C.machine_info(), "versions": C.our_versions(),
                 "revision": stamp["revision"]})
    data.setdefault("settings", {}).update(
        {"p0": P0, "radius": list(RADIUS), "density": DENSITY, **TEST, "setup": SETUP,
         "call_strain": CALL_STRAIN, "stepping_steps": STEPPING_STEPS})
    if exe is None:
        data["status"] = "skipped"
        data["reason"] = "YADE is not installed (no 'yade' executable on PATH)"
        print(data["reason"] + ": the peer is skipped")
    if part in ("all", "curves"):
        data["settings"].update(axial_strain=axial, seeds=seeds)
        curves(data, dims, axial, exe, seeds)
        data["measured_curves"] = stamp
    if part in ("all", "timing"):
        data["settings"].update(rounds=rounds, calls=calls)
        timing(data, rounds, calls, exe, dims)
        data["measured_timing"] = stamp
    data["loadavg_end"] = C.loadavg()
    data.setdefault("status", "ok")
    C.write_json(OUT, data)
    FIGURE.parent.mkdir(parents=True, exist_ok=True)
    visualize(data).savefig(FIGURE, dpi=120)


def worker(args):
    if args[0] == "timing":
        C.emit_result(ours_timing(export(int(args[2])), int(args[1])))


if __name__ == "__main__":
    C.entry(main, worker)
