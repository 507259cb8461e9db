"""Spheres in a rotating drum: a closed cylinder of triangles (a dem.MeshWall) turning
about its axis lifts the bed on its rising side.

The drum (radius 6 cm, 4 cm deep, axis y; 10 cm at full size) turns at ``OMEGA``
about +y, so that its bottom moves towards -x. Spheres of 5 mm radius fall into it
from a lattice, settle and are carried round. Claims checked by tests/test_examples.py:

- every sphere stays inside the drum (its centre within the drum's radius less its
  own, to a small overlap): the mesh holds them, the end caps too;
- the bed's centre of mass leans towards the rising side (x < 0): the friction of the
  turning wall lifts it;
- the drum's motor feeds the bed: the torque of the bed on the drum about its axis
  opposes the rotation, and the drum's work exceeds the bed's gain of potential and
  kinetic energy (the rest is dissipated in the contacts).

At the small size 138 spheres turn for 0.6 s; ``EXAMPLES_SIZE=full`` runs 552 for
2 s; run as a script it writes ``drum.h5`` with its XDMF files (``drum_meshes.xdmf``:
the turning drum) for ParaView, and its figure (into ``docs/figures/`` with
``--docs``).
"""

import os
from pathlib import Path

import numpy as np

import dem
import dem.io
from dem.io.hdf5 import figure_path

SIZE = os.environ.get("EXAMPLES_SIZE", "small")
DRUM_R, R, RHO = 0.06, 0.005, 2500.0  # [m], [m], [kg/m^3]
DEPTH = {"small": 0.04, "full": 0.1}[SIZE]  # [m]
OMEGA = 4.0  # [rad/s], about +y (Froude number omega^2 R / g of about 0.1)
N_SEG = 48  # sides of the polygon that approximates the drum
T_END = {"small": 0.6, "full": 2.0}[SIZE]  # [s]
LAYERS = {"small": 2, "full": 8}[SIZE]  # lattice layers along the axis


def drum_mesh(radius, depth, n_seg):
    """A closed cylinder about the y axis, centred at the origin: (vertices, faces)."""
    a = 2.0 * np.pi * np.arange(n_seg) / n_seg
    ring = np.column_stack([radius * np.cos(a), np.zeros(n_seg), radius * np.sin(a)])
    front, back = ring + [0.0, -0.5 * depth, 0.0], ring + [0.0, 0.5 * depth, 0.0]
    v = np.vstack([front, back, [[0.0, -0.5 * depth, 0.0], [0.0, 0.5 * depth, 0.0]]])
    k = np.arange(n_seg)
    nxt = (k + 1) % n_seg
    side = np.vstack([np.column_stack([k, nxt, n_seg + nxt]),
                      np.column_stack([k, n_seg + nxt, n_seg + k])])
    caps = np.vstack([np.column_stack([np.full(n_seg, 2 * n_seg), nxt, k]),
                      np.column_stack([np.full(n_seg, 2 * n_seg + 1), n_seg + k,
                                       n_seg + nxt])])
    return v, np.vstack([side, caps])


def lattice(n_layers):
    """Sphere centres on a cubic lattice inside the drum's upper part."""
    step = 2.2 * R
    ys = (np.arange(n_layers) - 0.5 * (n_layers - 1)) * step
    xs = np.arange(-0.045, 0.0451, step)
    zs = np.arange(-0.045, 0.0451, step)
    g = np.array([[x, y, z] for x in xs for y in ys for z in zs])
    inside = np.hypot(g[:, 0], g[:, 2]) < DRUM_R - 1.6 * R
    return g[inside]


vertices, faces = drum_mesh(DRUM_R, DEPTH, N_SEG)
drum = dem.MeshWall(vertices, faces, angular_velocity=[0.0, OMEGA, 0.0],
                    center=[0.0, 0.0, 0.0])
rng = np.random.default_rng(7)
pos = lattice(LAYERS)
pos += 2e-4 * rng.standard_normal(pos.shape)
bodies = dem.Bodies.spheres(pos, radius=R, density=RHO)
law = dem.LinearSpring(kn=2e4, kt=1e4, mu=0.5, restitution=0.5)
sim = dem.Simulation(bodies, law, gravity=[0.0, 0.0, -9.81], damping=0.0, walls=[drum])
n_spheres = bodies.n
mass = bodies.mass.sum()


def potential():
    return float(9.81 * np.sum(bodies.mass * bodies.pos[:, 2]))


def kinetic():
    return float(0.5 * np.sum(bodies.mass * np.sum(bodies.vel**2, axis=1))
                 + 0.5 * np.sum(bodies.inertia * bodies.ang_vel**2))


n_steps = int(T_END / sim.dt)
settle = n_steps // 3
sim.run(settle)  # the bed settles as the drum starts to turn
energy_before = potential() + kinetic()
work_before = float(sim.wall_work[0])
torques = []
for _ in range(10):
    sim.run((n_steps - settle) // 10)
    torques.append(sim.mesh_wall_forces()[1][0, 1])
energy_gain = potential() + kinetic() - energy_before
drum_work = float(sim.wall_work[0]) - work_before
torque_mean = float(np.mean(torques))  # of the bed on the drum, about +y [N m]
centroid = np.average(bodies.pos, axis=0, weights=bodies.mass)
lean = float(np.degrees(np.arctan2(-centroid[0], -centroid[2])))  # > 0: to -x
reach = float(np.max(np.hypot(bodies.pos[:, 0], bodies.pos[:, 2])))
span_y = float(np.max(np.abs(bodies.pos[:, 1])))


def visualize():
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(4, 4))
    a = np.linspace(0.0, 2.0 * np.pi, 200)
    ax.plot(DRUM_R * np.cos(a), DRUM_R * np.sin(a), "k-")
    for p in bodies.pos:
        ax.add_patch(plt.Circle((p[0], p[2]), R, fc="tab:orange", ec="k", lw=0.3))
    ax.plot(centroid[0], centroid[2], "b+", ms=12)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    ax.set_title(f"drum at {OMEGA:g} rad/s: bed leans {lean:.0f} deg")
    fig.tight_layout()
    return fig


if __name__ == "__main__":
    out = Path(os.environ.get("EXAMPLES_OUTPUT", "output")) / "rotating_drum"
    out.mkdir(parents=True, exist_ok=True)
    with dem.io.H5Writer(out / "drum.h5", every=max(1, n_steps // 100)) as writer:
        sim.observers.append(writer)
        sim.run(n_steps // 5)
    print(f"{n_spheres} spheres, {n_steps} steps of {sim.dt:.3g} s: bed leans {lean:.1f} "
          f"deg, drum torque {torque_mean:.3g} N m, work {drum_work:.3g} J "
          f"(energy gain {energy_gain:.3g} J); farthest centre {1e3 * reach:.2f} mm from "
          f"the axis (the drum's radius less a sphere's: {1e3 * (DRUM_R - R):.2f} mm), "
          f"{1e3 * span_y:.2f} mm from the middle plane (end caps less a sphere's: "
          f"{1e3 * (0.5 * DEPTH - R):.2f} mm); output {out / 'drum.h5'}")
    fig_path = figure_path("rotating_drum.png", out,
                           Path(__file__).resolve().parents[1] / "docs" / "figures")
    visualize().savefig(fig_path, dpi=120)
