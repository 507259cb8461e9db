"""Polygons colliding in the plane (paper Fig 4).

A loose cluster of random convex polygons (3 to 8 vertices, circumradius 0.08 to
0.12 m, density 1000 kg/m^3 per metre of thickness) rests in free space: no gravity, no
walls. One more polygon is launched at it with ``v0 = (0.25, 0.24) m/s``. Contacts
follow the paper's viscoelastic law: kn = 1e5 N/m, ks = 1e4 N/m, mu = 1,
gamma_n = 1 N s/m, gamma_s = sqrt(0.1) N s/m. Contact detection is the exact polygon
solver (``detection="admm"`` runs the same scene through ADMM).

Claims checked by tests/test_examples.py:

- the total linear momentum stays ``m v0`` and the angular momentum about the origin
  stays that of the launched polygon, to round-off: every contact force acts on both
  bodies, equal and opposite, at one point;
- the total energy (kinetic + elastic in the contacts) never grows between records by
  more than the integrator's error (1e-4 of the initial energy), and the dashpots and
  friction take a sizeable part of it by the end: the law is dissipative;
- the launched polygon hits the cluster and sets several polygons moving.

Outputs: ``output/ex03/polygons.h5`` + ``.xdmf`` (ParaView:
``polygons_shapes.xdmf`` shows the polygons, ``polygons_contacts.xdmf`` the contact
forces); run as a script it also writes ``ex03_polygons.png`` (start and end, and the
energy budget) into its output folder, or into ``docs/figures/`` with ``--docs``.

Small size: 12 polygons in the cluster, 1.5 s; ``EXAMPLES_SIZE=full``: 60 polygons, 4 s.
"""

import os
from pathlib import Path

import numpy as np

import dem
from dem.io import H5Writer
from dem.io.hdf5 import figure_path
from dem.observers import angular_momentum, elastic_energy, kinetic_energy
from dem.shapes import ConvexPolygon

SIZE = os.environ.get("EXAMPLES_SIZE", "small")
N_CLUSTER, T_END = (12, 1.5) if SIZE == "small" else (60, 4.0)
RHO = 1000.0
V0 = np.array([0.25, 0.24])
LAW = dem.Viscoelastic(kn=1e5, kt=1e4, gamma_n=1.0, gamma_t=np.sqrt(0.1), mu=1.0)
OUT = Path(os.environ.get("EXAMPLES_OUTPUT", "output")) / "ex03"
DETECTION = os.environ.get("EX03_DETECTION", "auto")


def random_polygon(rng, r_min=0.08, r_max=0.12):
    """A convex polygon: 3 to 8 vertices at random angles on a circle, jittered radii."""
    n = int(rng.integers(3, 9))
    angles = np.sort(rng.uniform(0.0, 2.0 * np.pi, n))
    angles += np.linspace(0.0, 2.0 * np.pi, n, endpoint=False) - angles.mean() + np.pi
    radius = rng.uniform(r_min, r_max) * rng.uniform(0.85, 1.0, n)
    return ConvexPolygon(np.stack([radius * np.cos(angles), radius * np.sin(angles)], 1))


def build(n_cluster, seed=4):
    """The cluster on a jittered square lattice and the launched polygon at its lower left."""
    rng = np.random.default_rng(seed)
    bodies = dem.Bodies.empty(2)
    side = int(np.ceil(np.sqrt(n_cluster)))
    spacing = 0.26
    for k in range(n_cluster):
        centre = spacing * np.array([k % side, k // side]) + rng.uniform(-0.01, 0.01, 2)
        bodies.add_shapes(random_polygon(rng), [centre], RHO, rot=[rng.uniform(0, 2 * np.pi)])
    shooter = bodies.add_shapes(random_polygon(rng), [[-0.35, -0.3]], RHO, rot=[0.3],
                                vel=[V0])
    return bodies, int(shooter[0])


def run(n_cluster=N_CLUSTER, t_end=T_END, detection=DETECTION, out=OUT):
    bodies, shooter = build(n_cluster)
    sim = dem.Simulation(bodies, LAW, detection=detection)
    b = sim.bodies
    start = b.copy()
    n_rec = 150
    every = max(1, int(round(t_end / sim.dt / n_rec)))
    rec = {k: [] for k in ("t", "kinetic", "elastic", "px", "py", "lz", "moving")}

    def record(s):
        rec["t"].append(s.time)
        rec["kinetic"].append(sum(kinetic_energy(s.bodies)))
        rec["elastic"].append(elastic_energy(s))
        p = (s.bodies.mass[:, None] * s.bodies.vel).sum(axis=0)
        rec["px"].append(p[0])
        rec["py"].append(p[1])
        rec["lz"].append(angular_momentum(s.bodies)[0])
        speed = np.linalg.norm(s.bodies.vel, axis=1)
        rec["moving"].append(int(np.sum(speed > 0.01)))

    out.mkdir(parents=True, exist_ok=True)
    writer = H5Writer(out / "polygons.h5", every=every * 10, contacts=True)
    sim.observers += [dem.Record(record, every=every), writer]
    record(sim)
    writer(sim)
    sim.run(int(round(t_end / sim.dt)))
    writer.close()
    rec = {k: np.array(v) for k, v in rec.items()}
    return sim, shooter, start, rec


def _draw(ax, bodies, colour):
    from matplotlib.patches import Polygon

    t = bodies.table
    for i in range(bodies.n):
        s = bodies.shape[i]
        v = t.verts[t.vstart[s]:t.vstart[s + 1], :2] * t.scale[s]
        c, sn = np.cos(bodies.rot[i, 0]), np.sin(bodies.rot[i, 0])
        world = v @ np.array([[c, sn], [-sn, c]]) + bodies.pos[i]
        ax.add_patch(Polygon(world, closed=True, fill=False, edgecolor=colour, lw=0.8))


def visualize():
    """The polygons at the start (grey) and end (blue), and the energy budget."""
    return figure(start, sim.bodies, rec)


def figure(start, end, rec):
    """:func:`visualize` of the bodies ``start`` and ``end`` and the records ``rec``
    of :func:`run`."""
    import matplotlib.pyplot as plt

    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 4.5), layout="constrained",
                                  gridspec_kw={"width_ratios": [1.1, 1]})
    _draw(ax, start, "0.6")
    _draw(ax, end, "C0")
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("polygons: start (grey) and end (blue)")
    total = rec["kinetic"] + rec["elastic"]
    ax2.plot(rec["t"], rec["kinetic"], label="kinetic")
    ax2.plot(rec["t"], rec["elastic"], label="elastic (contacts)")
    ax2.plot(rec["t"], total, "k--", label="total")
    ax2.set_xlabel("time [s]")
    ax2.set_ylabel("energy [J]")
    ax2.set_title("energy budget")
    top = float(np.max(total))
    ax2.set_ylim(-0.03 * top, 1.45 * top)  # room above the curves for the legend
    ax2.legend(loc="upper center", ncol=3, fontsize=9)
    return fig


sim, shooter, start, rec = run()
b = sim.bodies
mass_shooter = float(b.mass[shooter])
momentum = np.stack([rec["px"], rec["py"]], axis=1)
momentum_expected = mass_shooter * V0
energy = rec["kinetic"] + rec["elastic"]
energy_rise = float(np.max(np.diff(energy)) / energy[0])
dissipated = float(1.0 - energy[-1] / energy[0])
lz = rec["lz"]
n_moving = int(rec["moving"][-1])

if __name__ == "__main__":
    print(f"momentum {momentum[-1]} kg m/s (launched: {momentum_expected})")
    print(f"largest energy rise between records: {energy_rise:.2e} of the initial energy")
    print(f"dissipated: {100 * dissipated:.1f} %; polygons moving at the end: {n_moving}")
    fig_path = figure_path("ex03_polygons.png",
                           OUT, Path(__file__).resolve().parents[1] / "docs" / "figures")
    fig_path.parent.mkdir(parents=True, exist_ok=True)
    visualize().savefig(fig_path, dpi=100)
    print(f"wrote {OUT}/polygons.h5 (+ .xdmf) and {fig_path}")
