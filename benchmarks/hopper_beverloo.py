"""Hopper discharge through an STL mesh and Beverloo's law.

A square bin (side ``BIN``) with a flat bottom pierced by a square orifice of width
``D`` is written as an STL file and read back as a :class:`dem.MeshWall`; spheres of
diameter ``d`` fill it from a lattice and drain under gravity. The mass flow rate ``W``
is measured while the bin is at least half full (the steady part of the discharge).
Beverloo's law, ``W = C rho_b sqrt(g) (D - k d)^beta`` with ``beta = 5/2`` in 3D, is
fitted with ``k`` fixed (``K_BEVERLOO``, 1.5 for square orifices in the literature's
range 1.2-2): the script reports the fitted exponent.

usage::

    python benchmarks/hopper_beverloo.py            # orifices 4-7 d, about 3,000 spheres
    HOPPER_SIZE=small python benchmarks/hopper_beverloo.py   # the tests' size

At full size it takes a long time (minutes per orifice); ``small`` runs two orifices of
a few hundred spheres for a fraction of a second and only shows that it works
(tests/dem/test_hopper_beverloo.py: the wider orifice drains faster).
"""

import os
import tempfile
from pathlib import Path

import numpy as np

import dem

SIZE = os.environ.get("HOPPER_SIZE", "full")
D_SPHERE, RHO, G = 0.004, 2500.0, 9.81  # [m], [kg/m^3], [m/s^2]
K_BEVERLOO = 1.5
SETTINGS = {
    "small": {"orifices": (3.0, 5.0), "bin": 8.0, "layers": 4, "t_end": 0.25},
    "full": {"orifices": (4.0, 5.0, 6.0, 7.0), "bin": 16.0, "layers": 14, "t_end": 3.0},
}[SIZE]


def bin_triangles(side, height, orifice):
    """(vertices, faces) of a square bin [-side/2, side/2]^2 x [0, height], open at
    the top, its bottom pierced by a centred square hole of width ``orifice``."""
    s, o = 0.5 * side, 0.5 * orifice
    outer = [[-s, -s], [s, -s], [s, s], [-s, s]]
    inner = [[-o, -o], [o, -o], [o, o], [-o, o]]
    v = [[x, y, 0.0] for x, y in outer + inner] + [[x, y, height] for x, y in outer]
    faces = []
    for k in range(4):  # the bottom: a frame of four trapezoids, two triangles each
        n = (k + 1) % 4
        faces += [[k, n, 4 + n], [k, 4 + n, 4 + k]]
    for k in range(4):  # the sides
        n = (k + 1) % 4
        faces += [[k, 8 + k, 8 + n], [k, 8 + n, n]]
    return np.array(v), np.array(faces)


def discharge(orifice_d, workdir):
    """Mass flow rate [kg/s] through an orifice ``orifice_d`` sphere diameters wide."""
    side = SETTINGS["bin"] * D_SPHERE
    height = (SETTINGS["layers"] + 2) * 1.1 * D_SPHERE
    v, f = bin_triangles(side, height, orifice_d * D_SPHERE)
    stl = Path(workdir) / f"bin_{orifice_d:g}.stl"
    dem.MeshWall(v, f).write(stl)
    hopper = dem.MeshWall.from_file(stl)
    step = 1.1 * D_SPHERE
    xs = np.arange(-0.5 * side + step, 0.5 * side - 0.5 * step, step)
    zs = 0.6 * D_SPHERE + step * np.arange(SETTINGS["layers"])
    pos = np.array([[x, y, z] for z in zs for x in xs for y in xs])
    rng = np.random.default_rng(1)
    pos[:, :2] += 0.02 * D_SPHERE * rng.standard_normal((pos.shape[0], 2))
    bodies = dem.Bodies.spheres(pos, radius=0.5 * D_SPHERE, density=RHO)
    law = dem.LinearSpring(kn=1e4, kt=5e3, mu=0.5, restitution=0.5)
    sim = dem.Simulation(bodies, law, gravity=[0.0, 0.0, -G], walls=[hopper])
    n, half = bodies.n, bodies.n // 2
    times, out = [], []
    every = max(1, int(0.005 / sim.dt))
    while sim.time < SETTINGS["t_end"]:
        sim.run(every)
        times.append(sim.time)
        out.append(int(np.count_nonzero(bodies.pos[:, 2] < -D_SPHERE)))
        if out[-1] >= half:
            break
    times, out = np.array(times), np.array(out)
    flowing = (out > 0.05 * n) & (out < half)
    if np.count_nonzero(flowing) < 2:
        return 0.0, n
    rate = np.polyfit(times[flowing], out[flowing], 1)[0]  # spheres per second
    return float(rate * bodies.mass[0]), n


def beverloo_exponent(orifices, rates):
    """The exponent beta of the fit W = c (D - k d)^beta (least squares in logs)."""
    x = np.log(np.asarray(orifices) - K_BEVERLOO)
    return float(np.polyfit(x, np.log(rates), 1)[0])


def main():
    with tempfile.TemporaryDirectory() as work:
        runs = [discharge(o, work) for o in SETTINGS["orifices"]]
    rates = [r for r, _ in runs]
    return SETTINGS["orifices"], rates, runs[0][1]


if __name__ == "__main__":
    orifices, rates, n = main()
    for o, w in zip(orifices, rates, strict=True):
        print(f"D = {o:g} d: W = {w:.4g} kg/s")
    if all(w > 0 for w in rates) and len(rates) > 1:
        print(f"Beverloo exponent (k = {K_BEVERLOO}): {beverloo_exponent(orifices, rates):.2f} "
              f"(theory 2.5), {n} spheres")
