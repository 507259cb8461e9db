"""Peridynamics against LAMMPS's PERI package on the same scene.

LAMMPS's own PMB example scene (``examples/peri/in.peri.pmb``: a cylinder of radius
5 mm and height 5 mm on a simple cubic lattice, micromodulus 1.6863e22 N/m^6, horizon
3 lattice spacings, critical stretch 5e-4, density 2200 kg/m^3), at a finer lattice
spacing so the scene has about 25,000 points. Instead of the example's indenter (a force
field that has no counterpart here) every point starts with the radial velocity
``v = rate * (x, 0, z)``, so that bonds stretch and break from the outside in. Both codes
run the same points, bonds, time step (1e-8 s) and number of steps on one core; we
report the time per step, the ratio, and the mean damage and kinetic energy at
the end (the physics should agree; LAMMPS scales the volume of neighbours cut by the
horizon, which moves its numbers by a few percent).

A second part runs the shared peer scene (``../shared/bench/pd_lammps/in.pd``: LAMMPS's
peridynamic target cylinder, radius 3.7 mm, height 5 mm, simple cubic lattice of 0.5 mm,
1,947 points, horizon 1.5001 mm, density 2200 kg/m^3, a velocity ramp of +-1 m/s along
the axis, velocity Verlet at 1e-7 s) with both of LAMMPS's models, ``peri/lps`` (bulk =
shear modulus = 14.9 GPa; ours ``LPS(E = 9KG / (3K + G), nu = (3K - 2G) / (6K + 2G))``)
and ``peri/pmb`` (micromodulus 1.6863e22 N/m^6; ours ``PMB`` with the modulus whose
lattice-calibrated micromodulus is that), with intact bonds: the critical stretch is 1
in LAMMPS (no bond reaches it; LAMMPS steps once at rest first, see
:func:`lammps_shared`) and none in ours; both report their broken bonds (none). Both
count the same bond entries (each bond once from each end); ``ratio_lps`` and
``ratio_pmb`` are our bond-updates per second over LAMMPS's, one thread against one
core, medians of ``REPEAT`` runs of ``SHARED["steps"]`` steps. What differs: LAMMPS's
pair styles also push apart every two points closer than a short contact distance (part
of their cost; ours keeps its own contact list of bodies not joined by a bond), and the
LPS influence functions are each code's own (ours ``exp(-|xi|^2 / delta^2)``). The
kinetic energies at the end are reported beside the speeds; the body vibrates, so an end
value is a phase of its vibration, not a check of the physics.

Writes benchmarks/results/pd_lammps.json. Run: python benchmarks/pd_lammps.py
(NUMBA_NUM_THREADS=1 is set by the script; LAMMPS is ``lmp``; skipped, and said so,
when it is not installed).
"""

import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np

import dem
from dem import peridynamics as pd

SPACING = 0.00025                 # lattice spacing [m]
RADIUS, HEIGHT = 0.005, 0.005     # cylinder along y [m]
C, S00, RHO = 1.6863e22, 0.0005, 2200.0
HORIZON = 3.0001 * SPACING
DT, STEPS, REPEAT = 1e-8, 400, 3
RATE = 1.0e3                      # radial velocity gradient [1/s]: 5 m/s at the rim


#: the shared peer scene (../shared/bench/pd_lammps/in.pd), bonds kept intact
SHARED = {"spacing": 5e-4, "radius": 3.7e-3, "y": (-2.5e-3, 2.5e-3), "horizon": 1.5001e-3,
          "density": 2200.0, "bulk": 14.9e9, "shear": 14.9e9, "c": 1.6863e22,
          "ramp": 1.0, "dt": 1e-7, "steps": 1000}


def lattice_points(spacing=SPACING, radius=RADIUS, y=(-HEIGHT, 0.0)):
    """Simple cubic lattice points inside the cylinder along y of ``radius`` between
    ``y``, as LAMMPS's create_atoms puts them (the lattice's origin at 0, points on the
    region's boundary included)."""
    n = int(np.ceil(radius / spacing)) + 1
    ax = np.arange(-n, n + 1) * spacing
    ay = np.arange(int(np.floor(y[0] / spacing)) - 1, int(np.ceil(y[1] / spacing)) + 2) * spacing
    x, yy, z = np.meshgrid(ax, ay, ax, indexing="ij")
    p = np.stack([x.ravel(), yy.ravel(), z.ravel()], axis=1)
    eps = 1e-9 * spacing
    inside = (p[:, 0] ** 2 + p[:, 2] ** 2 <= radius**2 + eps) & (p[:, 1] >= y[0] - eps) & (
        p[:, 1] <= y[1] + eps)
    return p[inside]


def pmb_modulus(bodies, ids, horizon, density, c):
    """The modulus E whose lattice-calibrated PMB micromodulus is ``c``."""
    probe = pd.PDSimulation(bodies.copy(), pd.PMB(E=1e9, density=density), ids, horizon)
    return 1e9 * c / probe.params[3]


def ours():
    pos = lattice_points()
    bodies = dem.Bodies.empty(3)
    ids = pd.add_points(bodies, pos, SPACING, RHO)
    # the elastic modulus whose lattice-calibrated micromodulus is LAMMPS's c
    material = pd.PMB(E=pmb_modulus(bodies, ids, HORIZON, RHO, C), density=RHO, s_crit=S00)
    times, sim = [], None
    for _ in range(REPEAT):
        b = bodies.copy()
        b.vel[:, 0], b.vel[:, 2] = RATE * b.pos[:, 0], RATE * b.pos[:, 2]
        sim = pd.PDSimulation(b, material, ids, HORIZON, dt=DT)
        sim.run(2)  # compile and prime outside the clock
        t = time.perf_counter()
        sim.run(STEPS)
        times.append((time.perf_counter() - t) / STEPS)
    broken = float(sim.family.broken.mean())
    return {"points": int(pos.shape[0]), "bonds": int(sim.family.n_bonds // 2),
            "s_per_step": statistics.median(times), "broken_fraction": broken,
            "mean_damage": float(sim.damage().mean()),
            "kinetic_energy": sim.kinetic_energy(), "dt_crit": sim.dt_crit}


LAMMPS_INPUT = """
units si
boundary s s s
atom_style peri
atom_modify map array
neighbor {skin} bin
lattice sc {a}
region target cylinder y 0.0 0.0 {R} -{H} 0.0 units box
create_box 1 target
create_atoms 1 region target
pair_style peri/pmb
pair_coeff * * {c} {horizon} {s00} 0.0
set group all density {rho}
set group all volume {vol}
variable vx atom {rate}*x
variable vz atom {rate}*z
velocity all set v_vx 0.0 v_vz units box
fix 1 all nve
compute dmg all damage/atom
compute dsum all reduce ave c_dmg
thermo_style custom step ke c_dsum
thermo {steps}
timestep {dt}
run {steps}
"""


def run_lammps(exe, text, steps, last_step, volume):
    """Run LAMMPS ``REPEAT`` times on the input ``text`` (thermo ``step ke c_dsum``):
    the loop times [s] of its last ``run``, which must be of ``steps`` steps, its atom
    count, and the kinetic energy [J] and mean damage of the thermo line at
    ``last_step``. ``atom_style peri`` keeps the density as the mass, so its kinetic
    energy is per volume: it is multiplied by each point's ``volume``."""
    times, out, loop = [], "", None
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "in.pd"
        path.write_text(text)
        for _ in range(REPEAT):
            out = subprocess.run([exe, "-in", str(path), "-log", "none"], cwd=tmp,
                                 capture_output=True, text=True, check=True).stdout
            loop = re.findall(r"Loop time of ([0-9.eE+-]+) on \d+ procs for (\d+) steps "
                              r"with (\d+) atoms", out)[-1]
            if int(loop[1]) != steps:
                raise RuntimeError(f"LAMMPS timed {loop[1]} steps, not {steps}")
            times.append(float(loop[0]))
    last = [ln.split() for ln in out.splitlines()
            if ln.strip().startswith(str(last_step) + " ")]
    _, ke, dmg = last[-1][:3]
    return {"points": int(loop[2]), "runs_s": times, "kinetic_energy": float(ke) * volume,
            "mean_damage": float(dmg)}


def lammps(exe):
    text = LAMMPS_INPUT.format(skin=SPACING, a=SPACING, R=RADIUS, H=HEIGHT, c=C,
                               horizon=HORIZON, s00=S00, rho=RHO, vol=SPACING**3,
                               rate=RATE, steps=STEPS, dt=DT)
    r = run_lammps(exe, text, STEPS, STEPS, SPACING**3)
    return {"points": r["points"], "s_per_step": statistics.median(r["runs_s"]) / STEPS,
            "kinetic_energy": r["kinetic_energy"], "mean_damage": r["mean_damage"]}


def ours_shared(model):
    """Our run of the shared scene with ``model`` ("lps" or "pmb"), bonds intact."""
    sc = SHARED
    pos = lattice_points(sc["spacing"], sc["radius"], sc["y"])
    bodies = dem.Bodies.empty(3)
    ids = pd.add_points(bodies, pos, sc["spacing"], sc["density"])
    if model == "lps":
        k, g = sc["bulk"], sc["shear"]
        material = pd.LPS(E=9.0 * k * g / (3.0 * k + g),
                          nu=(3.0 * k - 2.0 * g) / (6.0 * k + 2.0 * g), density=sc["density"])
    else:
        material = pd.PMB(E=pmb_modulus(bodies, ids, sc["horizon"], sc["density"], sc["c"]),
                          density=sc["density"])
    y0, y1 = sc["y"]
    bodies.vel[:, 1] = sc["ramp"] * (2.0 * (bodies.pos[:, 1] - y0) / (y1 - y0) - 1.0)
    pd.PDSimulation(bodies.copy(), material, ids, sc["horizon"], dt=sc["dt"]).run(2)  # compile
    times, sim = [], None
    for _ in range(REPEAT):
        sim = pd.PDSimulation(bodies.copy(), material, ids, sc["horizon"], dt=sc["dt"])
        sim.prime()  # the forces of the initial state, outside the clock as LAMMPS's setup
        t = time.perf_counter()
        sim.run(sc["steps"])
        times.append(time.perf_counter() - t)
    entries = int(sim.family.n_bonds)
    loop = statistics.median(times)
    return {"points": int(pos.shape[0]), "bond_entries": entries, "loop_s": loop,
            "runs_s": times, "bond_updates_per_s": entries * sc["steps"] / loop,
            "broken_fraction": float(sim.family.broken.mean()),
            "kinetic_energy": sim.kinetic_energy()}


SHARED_INPUT = """
units si
boundary s s s
atom_style peri
atom_modify map array
neighbor 0.0010 bin
lattice sc {a}
region target cylinder y 0.0 0.0 {R} {y0} {y1} units box
create_box 1 target
create_atoms 1 region target
{pair}
set group all density {rho}
set group all volume {vol}
velocity all set 0.0 0.0 0.0 sum no units box
fix F1 all nve
compute dmg all damage/atom
compute dsum all reduce ave c_dmg
thermo_style custom step ke c_dsum
thermo {steps}
timestep {dt}
run 1
velocity all ramp vy -{v} {v} y {y0} {y1} sum yes units box
run {steps}
"""


def lammps_shared(exe, model, entries):
    """LAMMPS's run of the shared scene with ``model``, critical stretch 1 (intact).

    One step at rest comes first: LAMMPS's ``peri/lps`` starts every point's critical
    stretch at zero and sets it (``s00 - alpha * min stretch``) only after a step, so
    that a body given its velocities at once loses every bond in tension at the first
    step (74 % of them here, whatever ``s00``); at rest nothing stretches. The timed
    run is the second."""
    sc = SHARED
    pair = (f"pair_style peri/lps\npair_coeff * * {sc['bulk']} {sc['shear']} "
            f"{sc['horizon']} 1.0 0.25" if model == "lps" else
            f"pair_style peri/pmb\npair_coeff * * {sc['c']} {sc['horizon']} 1.0 0.25")
    text = SHARED_INPUT.format(a=sc["spacing"], R=sc["radius"], y0=sc["y"][0],
                               y1=sc["y"][1], pair=pair, rho=sc["density"],
                               vol=sc["spacing"] ** 3, v=sc["ramp"], steps=sc["steps"],
                               dt=sc["dt"])
    r = run_lammps(exe, text, sc["steps"], sc["steps"] + 1, sc["spacing"] ** 3)
    median = statistics.median(r["runs_s"])
    return dict(r, loop_s=median, bond_updates_per_s=entries * sc["steps"] / median)


def shared(exe):
    """The shared scene, LPS and PMB, ours and LAMMPS's interleaved."""
    out = {"scene": dict(SHARED, y=list(SHARED["y"]), repeat=REPEAT,
                         bonds="intact (critical stretch 1 in LAMMPS, none in ours)")}
    for model in ("lps", "pmb"):
        o = ours_shared(model)
        row = {"ours": o}
        print(f"shared scene, {model}: ours {o['points']} points, {o['bond_entries']} bond "
              f"entries, {o['loop_s']:.2f} s for {SHARED['steps']} steps "
              f"({o['bond_updates_per_s']:.3g} bond-updates/s), KE {o['kinetic_energy']:.4g} J",
              flush=True)
        if exe is not None:
            lm = lammps_shared(exe, model, o["bond_entries"])
            row["lammps"] = lm
            out[f"ratio_{model}"] = o["bond_updates_per_s"] / lm["bond_updates_per_s"]
            print(f"shared scene, {model}: LAMMPS {lm['points']} points, {lm['loop_s']:.2f} s "
                  f"({lm['bond_updates_per_s']:.3g} bond-updates/s), KE "
                  f"{lm['kinetic_energy']:.4g} J; ours / LAMMPS "
                  f"{out[f'ratio_{model}']:.2f}", flush=True)
        out[model] = row
    return out


def main():
    result = {"scene": {"spacing": SPACING, "radius": RADIUS, "height": HEIGHT,
                        "horizon": HORIZON, "dt": DT, "steps": STEPS, "repeat": REPEAT}}
    result["ours"] = o = ours()
    print(f"ours:   {o['points']} points, {o['bonds']} bonds, "
          f"{o['s_per_step'] * 1e3:.2f} ms/step, mean damage {o['mean_damage']:.4f}, "
          f"KE {o['kinetic_energy']:.4g} J")
    exe = shutil.which("lmp")
    if exe is None:
        print("LAMMPS (lmp) is not installed: peer skipped")
        result["lammps"] = None
    else:
        result["lammps"] = lm = lammps(exe)
        result["time_ratio_ours_over_lammps"] = o["s_per_step"] / lm["s_per_step"]
        print(f"LAMMPS: {lm['points']} points, {lm['s_per_step'] * 1e3:.2f} ms/step, "
              f"mean damage {lm['mean_damage']:.4f}, KE {lm['kinetic_energy']:.4g} J")
        print(f"time per step, ours / LAMMPS: {result['time_ratio_ours_over_lammps']:.2f}")
    result["shared_scene"] = sh = shared(exe)
    for key in ("ratio_lps", "ratio_pmb"):
        result[key] = sh.get(key)
    out = Path(__file__).parent / "results" / "pd_lammps.json"
    out.write_text(json.dumps(result, indent=1))
    print(f"wrote {out}")


if __name__ == "__main__":
    sys.exit(main())
