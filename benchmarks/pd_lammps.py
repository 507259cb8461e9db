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


def lattice_points():
    """Simple cubic lattice points inside the cylinder, as LAMMPS's create_atoms puts
    them (the lattice's origin at 0, points on the region's boundary included)."""
    n = int(np.ceil(RADIUS / SPACING)) + 1
    ax = np.arange(-n, n + 1) * SPACING
    ay = np.arange(-int(np.ceil(HEIGHT / SPACING)) - 1, 1) * SPACING
    x, y, z = np.meshgrid(ax, ay, ax, indexing="ij")
    p = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    eps = 1e-9 * SPACING
    inside = (p[:, 0] ** 2 + p[:, 2] ** 2 <= RADIUS**2 + eps) & (p[:, 1] >= -HEIGHT - eps) & (
        p[:, 1] <= eps)
    return p[inside]


def ours():
    pos = lattice_points()
    bodies = dem.Bodies.empty(3)
    ids = pd.add_points(bodies, pos, SPACING, RHO)
    # the elastic modulus whose lattice-calibrated micromodulus is LAMMPS's c
    probe = pd.PDSimulation(bodies.copy(), pd.PMB(E=1e9, density=RHO), ids, HORIZON)
    E = 1e9 * C / probe.params[3]
    material = pd.PMB(E=E, density=RHO, s_crit=S00)
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


def lammps(exe):
    text = LAMMPS_INPUT.format(skin=SPACING, a=SPACING, R=RADIUS, H=HEIGHT, c=C,
                               horizon=HORIZON, s00=S00, rho=RHO, vol=SPACING**3,
                               rate=RATE, steps=STEPS, dt=DT)
    times, out = [], ""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "in.pd"
        path.write_text(text)
        for _ in range(REPEAT):
            out = subprocess.run([exe, "-in", str(path), "-log", "none"], cwd=tmp,
                                 capture_output=True, text=True, check=True).stdout
            loop = re.search(r"Loop time of ([0-9.eE+-]+) on (\d+) procs for (\d+) steps "
                             r"with (\d+) atoms", out)
            times.append(float(loop.group(1)) / STEPS)
    last = [ln.split() for ln in out.splitlines() if ln.strip().startswith(str(STEPS))]
    _, ke, dmg = last[-1][:3]
    # atom_style peri keeps the density as the mass: its kinetic energy is per volume
    return {"points": int(loop.group(4)), "s_per_step": statistics.median(times),
            "kinetic_energy": float(ke) * SPACING**3, "mean_damage": float(dmg)}


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
    out = Path(__file__).parent / "results" / "pd_lammps.json"
    out.write_text(json.dumps(result, indent=1))
    print(f"wrote {out}")


if __name__ == "__main__":
    sys.exit(main())
