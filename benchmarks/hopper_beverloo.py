"""Hopper discharge through an STL mesh and Beverloo's law.

A square bin (side ``BIN``) with a flat bottom pierced by a square orifice of width
``D`` is written as an STL file and read back as a :class:`dem.MeshWall`; spheres of
diameter ``d`` fill it from a lattice and drain under gravity. The head is held
constant, as in the laboratory's steady discharge: a sphere that has fallen ``2 d``
below the orifice is counted and put back, at rest, in a free slot of two layers above
the bed (a slot is free when no sphere is within 1.05 d of it). The mass flow
rate ``W`` is the slope of the discharged mass against time after the first
``SKIP`` of the run (the start-up of the flow). Beverloo's law,
``W = C rho_b sqrt(g) (D - k d)^beta`` with ``beta = 5/2`` in 3D, is fitted with ``k``
fixed (``K_BEVERLOO``, 1.5 for square orifices in the literature's range 1.2-2): the
script reports the fitted exponent, and the ``k`` for which ``beta = 5/2`` fits best
(``W^(2/5)`` linear in ``D``).

usage::

    python benchmarks/hopper_beverloo.py            # orifices 4-7 d, 2,744 spheres
    python benchmarks/hopper_beverloo.py --plot     # redraws the figure from the JSON
    HOPPER_SIZE=small python benchmarks/hopper_beverloo.py   # the tests' size

At full size it takes some minutes per orifice and writes
``benchmarks/results/hopper_beverloo.json`` and ``docs/figures/hopper_beverloo.png``;
``small`` runs two orifices of 144 spheres for a fraction of a simulated second and
only shows that it works (tests/dem/test_hopper_beverloo.py: the wider orifice drains
faster).
"""

import os
import tempfile
from pathlib import Path

import numpy as np

import dem

SIZE = os.environ.get("HOPPER_SIZE", "full")
D_SPHERE, RHO, G = 0.004, 2500.0, 9.81  # [m], [kg/m^3], [m/s^2]
K_BEVERLOO = 1.5
SKIP = 0.3  # the part of the run left out of the rate (the flow starting)
SETTINGS = {
    "small": {"orifices": (3.0, 5.0), "bin": 8.0, "layers": 4, "t_end": 0.25},
    "full": {"orifices": (4.0, 5.0, 6.0, 7.0), "bin": 16.0, "layers": 14, "t_end": 1.5},
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


def filled_bin(wall, side, layers, rng):
    """A simulation of spheres on a lattice of ``layers`` layers (spacing 1.1 d, jittered
    sideways by ``rng``) in a bin ``side`` wide, the triangle-mesh ``wall``, under
    gravity: ``(sim, xs, zs)``, the lattice's columns and layers."""
    step = 1.1 * D_SPHERE
    xs = np.arange(-0.5 * side + step, 0.5 * side - 0.5 * step, step)
    zs = 0.6 * D_SPHERE + step * np.arange(layers)
    pos = np.array([[x, y, z] for z in zs for x in xs for y in xs])
    pos[:, :2] += 0.02 * D_SPHERE * rng.standard_normal((pos.shape[0], 2))
    bodies = dem.Bodies.spheres(pos, radius=0.5 * D_SPHERE, density=RHO)
    law = dem.LinearSpring(kn=1e4, kt=5e3, mu=0.5, restitution=0.5)
    sim = dem.Simulation(bodies, law, gravity=[0.0, 0.0, -G], walls=[wall])
    return sim, xs, zs


def discharge(orifice_d, workdir):
    """Mass flow rate [kg/s] through an orifice ``orifice_d`` sphere diameters wide, and
    the number of spheres."""
    layers = SETTINGS["layers"]
    side = SETTINGS["bin"] * D_SPHERE
    step = 1.1 * D_SPHERE
    height = (layers + 5) * step
    v, f = bin_triangles(side, height, orifice_d * D_SPHERE)
    stl = Path(workdir) / f"bin_{orifice_d:g}.stl"
    dem.MeshWall(v, f).write(stl)
    rng = np.random.default_rng(1)
    sim, xs, zs = filled_bin(dem.MeshWall.from_file(stl), side, layers, rng)
    bodies = sim.bodies
    slots = np.array([[x, y, zs[-1] + k * step] for k in (2, 3) for x in xs for y in xs])
    every = max(1, int(0.005 / sim.dt))
    times, out, used = [], [], 0
    while sim.time < SETTINGS["t_end"]:
        sim.run(every)
        gone = np.flatnonzero(bodies.pos[:, 2] < -2.0 * D_SPHERE)
        if gone.size:
            near = np.linalg.norm(bodies.pos[:, None, :] - slots[None, :, :], axis=2)
            free = list(np.flatnonzero(near.min(axis=0) > 1.05 * D_SPHERE))
            for i in gone[:len(free)]:  # back on top, at rest, each in a free slot
                bodies.pos[i] = slots[free.pop(rng.integers(len(free)))]
                bodies.vel[i] = 0.0
                bodies.ang_vel[i] = 0.0
                used += 1
            sim.invalidate()  # the rest wait below for a slot to clear
        times.append(sim.time)
        out.append(used)
    times, out = np.array(times), np.array(out)
    steady = times >= SKIP * SETTINGS["t_end"]
    if out[-1] == 0:
        return 0.0, bodies.n
    rate = np.polyfit(times[steady], out[steady], 1)[0]  # spheres per second
    return float(rate * bodies.mass[0]), bodies.n


def beverloo_exponent(orifices, rates):
    """The exponent beta of the fit W = c (D - k d)^beta (least squares in logs)."""
    x = np.log(np.asarray(orifices) - K_BEVERLOO)
    return float(np.polyfit(x, np.log(rates), 1)[0])


def beverloo_k(orifices, rates):
    """k of Beverloo's law with beta = 5/2: W^(2/5) is linear in D, zero at D = k d."""
    slope, icpt = np.polyfit(np.asarray(orifices), np.asarray(rates) ** 0.4, 1)
    return float(-icpt / slope)


def main():
    with tempfile.TemporaryDirectory() as work:
        runs = []
        for o in SETTINGS["orifices"]:
            runs.append(discharge(o, work))
            print(f"  orifice {o:g} d: {runs[-1][0]:.4g} kg/s", flush=True)
    rates = [r for r, _ in runs]
    return SETTINGS["orifices"], rates, runs[0][1]


def plot(orifices, rates, beta, path):
    """W against D - k d on log axes, with the fitted and Beverloo's slopes."""
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FormatStrFormatter, NullFormatter

    x = np.asarray(orifices) - K_BEVERLOO
    fig, ax = plt.subplots(figsize=(4.5, 3.5))
    ax.loglog(x, rates, "o", label="measured")
    xs = np.geomspace(x.min(), x.max(), 20)
    c = np.exp(np.mean(np.log(rates) - beta * np.log(x)))
    ax.loglog(xs, c * xs ** beta, "-", label=f"fit, exponent {beta:.2f}")
    c25 = np.exp(np.mean(np.log(rates) - 2.5 * np.log(x)))
    ax.loglog(xs, c25 * xs ** 2.5, "--", label="Beverloo, 5/2")
    ax.set_xticks(x)
    ax.xaxis.set_major_formatter(FormatStrFormatter("%g"))
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel(f"(D - {K_BEVERLOO:g} d) / d")
    ax.set_ylabel("mass flow rate W [kg/s]")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    import json
    import sys
    import time

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import _common as C

    OUT = C.RESULTS / "hopper_beverloo.json"
    FIGURE = C.REPO / "docs" / "figures" / "hopper_beverloo.png"
    if "--plot" in sys.argv:  # redraw the figure from the JSON
        data = json.loads(OUT.read_text())
        plot(data["orifices_d"], data["mass_flow_rate_kg_s"], data["beverloo_exponent"],
             FIGURE)
        sys.exit(0)
    start = time.perf_counter()
    orifices, rates, n = main()
    wall = time.perf_counter() - start
    for o, w in zip(orifices, rates, strict=True):
        print(f"D = {o:g} d: W = {w:.4g} kg/s")
    if all(w > 0 for w in rates) and len(rates) > 1:
        beta = beverloo_exponent(orifices, rates)
        print(f"Beverloo exponent (k = {K_BEVERLOO}): {beta:.2f} (theory 2.5), {n} spheres, "
              f"{wall:.0f} s")
        if SIZE == "full":
            C.write_json(OUT, {
                "date": C.now(), "machine": C.machine_info(), "revision": C.git_revision(),
                "spheres": n, "sphere_diameter_m": D_SPHERE,
                "bin_width_d": SETTINGS["bin"], "orifices_d": list(orifices),
                "mass_flow_rate_kg_s": rates, "k_fixed": K_BEVERLOO,
                "beverloo_exponent": beta, "rel_exponent_deviation": abs(beta / 2.5 - 1.0),
                "k_for_exponent_2_5": beverloo_k(orifices, rates), "wall_s": wall})
            plot(orifices, rates, beta, FIGURE)
