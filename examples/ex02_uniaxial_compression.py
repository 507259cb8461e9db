"""Uniaxial compression of hex-packed spheres in a box (paper Figs 7 and 8).

Equal spheres (radius 0.5 m) fill a box in a hexagonal close packing: hexagonal layers
stacked ABAB (HCP) along z, every sphere touching its neighbours. The box is six planes,
each touching the outermost spheres; the lid moves down at 0.35 m/s and the other walls
stay put, so the packing is strained along z with no lateral strain (oedometric
loading). Sphere-sphere
contacts follow the paper's viscoelastic law: kn = 20 N/m, ks = kn / 2,
gamma_n = 0.08 N s/m, gamma_s = gamma_n / 2, mu = 0.3. Sphere-wall contacts use the same
springs and dashpots without friction (smooth, lubricated platens and side walls): with
friction the side walls carry part of the load (Janssen) and the lid force no longer
measures the stress inside the box.

The density, 1e-3 kg/m^3 (a sphere weighs 0.52 g), keeps the soft springs
quasi-static at this loading rate: the lattice's wave speed ``2 R sqrt(kn / m)`` is
about 200 m/s, over 500 times the lid speed, and the normal dashpot damps a contact at
about half its critical value. The time step is the default,
``dem.DT_FACTOR * sim.dt_crit``.

The stress is the homogenised Cauchy stress of the spheres (paper eq 24, tension
positive) from a :class:`dem.CollectionTracker` whose volume is the current box volume.

A second, small run compresses the same layers (8 x 8 x 6) in a cell that is periodic
in x and y, with only the floor and the lid as walls: a laterally infinite crystal, the
bulk that the box approximates.

Claims checked by tests/test_examples.py:

- sigma_zz is compressive and grows in magnitude with the axial strain once the
  packing carries load;
- at the end, sigma_zz from the contacts equals minus the lid's force over the lid area
  within a few per cent (equilibrium of the box: the sum over contacts of force times
  arm reduces to the wall contacts; the contact points lie half an overlap beyond the
  walls, which adds overlap / height, about 1 %), and the floor carries what the lid
  does;
- the lateral stresses are compressive, smaller than the axial one, and the side walls'
  forces over their areas give the same sigma_xx and sigma_yy as the contacts;
- in the bulk cell, sigma_xx = sigma_yy and the shear stresses vanish, to round-off: the
  hexagonal layers make the crystal transversely isotropic about z.

In the box itself sigma_xx and sigma_yy differ, by 10 % at the small size and 40 % at
the full size: planes cannot close a hexagonal crystal. Every other row of a layer ends
a radius short of an x wall, and A and B layers touch opposite y walls, a gap of
r / sqrt(3) from the other; and the stack shears in the y-z plane, its layers shifting
along y (sigma_yz is 1 to 2 % of sigma_zz). The test does not claim the box is
isotropic.

Small size: 8 x 8 spheres per layer, 6 layers (384 spheres); ``EXAMPLES_SIZE=full``:
25 x 30 per layer, 22 layers (16,500 spheres, the paper's size). Both are compressed to
4 % axial strain.
"""

import os
from pathlib import Path

import numpy as np

import dem
from dem.io.hdf5 import figure_path
from dem.io.packing import hcp_layers

SIZE = os.environ.get("EXAMPLES_SIZE", "small")

RADIUS = 0.5  # [m]
DENSITY = 1.0e-3  # [kg/m^3]
LID_SPEED = 0.35  # [m/s]
STRAIN_END = 0.04  # axial strain at the end of the run
# spheres per row, rows per layer, layers
N_X, N_Y, N_Z = {"small": (8, 8, 6), "full": (25, 30, 22)}[SIZE]
N_RECORDS = 60
SPRINGS = dict(kn=20.0, kt=10.0, gamma_n=0.08, gamma_t=0.04)  # [N/m], [N s/m]


def compress(bodies, lid, area, box=None):
    """Drive the lid down to ``STRAIN_END``; return the simulation and its records.

    The stress is recorded over the current volume ``area x lid height``; the wall
    forces (dict: wall body index -> (n_records, 3) [N]) at the same steps.
    """
    model = dem.ContactModel(dem.Viscoelastic(**SPRINGS, mu=0.3),
                             wall_law=dem.Viscoelastic(**SPRINGS, mu=0.0))
    h0 = float(bodies.pos[lid, 2])
    dt = dem.DT_FACTOR * dem.critical_time_step(bodies, model)[0]
    n_steps = int(round(STRAIN_END * h0 / LID_SPEED / dt))
    every = max(1, n_steps // N_RECORDS)
    n_steps -= n_steps % every  # the last record is the final state
    walls = bodies.ids(dem.Shape.PLANE)
    stress_log = dem.CollectionTracker(
        volume=lambda sim: area * float(sim.bodies.pos[lid, 2]), every=every)
    wall_log = dem.Record(
        lambda sim: np.array([sim.wall_forces()[w] for w in walls]), every=every)
    lid_log = dem.Record(lambda sim: float(sim.bodies.pos[lid, 2]), every=every)
    sim = dem.Simulation(bodies, model, dt=dt, box=box,
                         observers=[stress_log, wall_log, lid_log])
    sim.run(n_steps)
    height = np.array(lid_log.values)
    forces = dict(zip(walls.tolist(), np.moveaxis(np.array(wall_log.values), 1, 0),
                      strict=True))
    return sim, (h0 - height) / h0, height, np.array(stress_log.stress), forces


# ---------------------------------------------------------------- the box
pos0 = hcp_layers(N_X, N_Y, N_Z, RADIUS)
LX = N_X * 2.0 * RADIUS + RADIUS  # every other row is shifted by one radius
LY = pos0[:, 1].max() + RADIUS
H0 = pos0[:, 2].max() + RADIUS
AREA = LX * LY  # lid area [m^2]
bodies = dem.Bodies.spheres(pos0, radius=RADIUS, density=DENSITY)
WALLS = {
    "x0": bodies.add_plane([0.0, 0.0, 0.0], [1.0, 0.0, 0.0]),
    "x1": bodies.add_plane([LX, 0.0, 0.0], [-1.0, 0.0, 0.0]),
    "y0": bodies.add_plane([0.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
    "y1": bodies.add_plane([0.0, LY, 0.0], [0.0, -1.0, 0.0]),
    "floor": bodies.add_plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
    "lid": bodies.add_plane([0.0, 0.0, H0], [0.0, 0.0, -1.0],
                            velocity=[0.0, 0.0, -LID_SPEED]),
}
sim, strain, height, stress, forces = compress(bodies, WALLS["lid"], AREA)
dt = sim.dt
n_steps = sim.step

sigma_xx, sigma_yy, sigma_zz = stress[:, 0, 0], stress[:, 1, 1], stress[:, 2, 2]
wall_force = {name: forces[w] for name, w in WALLS.items()}  # (n_records, 3) [N]
# the force F a wall takes from the packing gives the stress on that face:
# sigma_nn = (F . n) / area with n the wall's inward normal (compression negative)
sigma_zz_lid = -wall_force["lid"][:, 2] / AREA
sigma_zz_floor = wall_force["floor"][:, 2] / AREA
sigma_xx_walls = 0.5 * (wall_force["x0"][:, 0] - wall_force["x1"][:, 0]) / (LY * height)
sigma_yy_walls = 0.5 * (wall_force["y0"][:, 1] - wall_force["y1"][:, 1]) / (LX * height)
loaded = strain > 0.25 * STRAIN_END  # past the start-up transient of the lid's impact

# ---------------------------------------------------------------- the bulk cell
# The same layers, 8 x 8 x 6, periodic in x and y: no side walls, so the lattice is
# infinite sideways and its hexagonal symmetry holds exactly.
BULK_N = (8, 8, 6)  # an even number of rows, so that the rows tile the period
bulk_pos = hcp_layers(*BULK_N, RADIUS)
BULK_SIZE = np.array([BULK_N[0] * 2.0 * RADIUS, BULK_N[1] * np.sqrt(3.0) * RADIUS,
                      bulk_pos[:, 2].max() + RADIUS])  # periods in x, y; lid height
bulk_pos[:, :2] %= BULK_SIZE[:2]
bulk_bodies = dem.Bodies.spheres(bulk_pos, radius=RADIUS, density=DENSITY)
bulk_bodies.add_plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
bulk_lid = bulk_bodies.add_plane([0.0, 0.0, BULK_SIZE[2]], [0.0, 0.0, -1.0],
                                 velocity=[0.0, 0.0, -LID_SPEED])
bulk_box = dem.Domain(lo=[0.0, 0.0, 0.0], hi=BULK_SIZE, periodic=[True, True, False])
_, bulk_strain, _, bulk_stress, _ = compress(
    bulk_bodies, bulk_lid, BULK_SIZE[0] * BULK_SIZE[1], box=bulk_box)


def visualize():
    """Stress against axial strain: contacts (lines), walls (markers), bulk (dots)."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    pct = 100.0 * strain
    ax.plot(pct, -sigma_zz, "-", color="C0", label=r"$-\sigma_{zz}$, contacts (eq 24)")
    ax.plot(pct, -sigma_xx, "-", color="C1", label=r"$-\sigma_{xx}$, contacts")
    ax.plot(pct, -sigma_yy, "-", color="C2", label=r"$-\sigma_{yy}$, contacts")
    mark = slice(None, None, 4)
    ax.plot(pct[mark], -sigma_zz_lid[mark], "o", mfc="none", color="C0", ms=5,
            label="lid force / area")
    ax.plot(pct[mark], -sigma_xx_walls[mark], "s", mfc="none", color="C1", ms=4,
            label="x walls")
    ax.plot(pct[mark], -sigma_yy_walls[mark], "^", mfc="none", color="C2", ms=4,
            label="y walls")
    ax.plot(100.0 * bulk_strain, -bulk_stress[:, 0, 0], ":", color="k", lw=1.5,
            label=r"$-\sigma_{xx} = -\sigma_{yy}$, periodic cell")
    ax.set_xlabel("axial strain [%]")
    ax.set_ylabel("compressive stress [Pa]")
    ax.set_title(f"uniaxial compression of {N_X * N_Y * N_Z} HCP spheres in a box")
    ax.legend(frameon=False, fontsize=9)
    fig.tight_layout()
    return fig


if __name__ == "__main__":
    print(f"{SIZE}: {N_X * N_Y * N_Z} spheres, box {LX:.3f} x {LY:.3f} x {H0:.3f} m, "
          f"{n_steps} steps of dt = {dt:.3e} s (dt_crit = {sim.dt_crit:.3e} s)")
    print(f"axial strain {strain[-1]:.4f}: sigma_zz = {sigma_zz[-1]:.4f} Pa "
          f"(lid {sigma_zz_lid[-1]:.4f}, floor {sigma_zz_floor[-1]:.4f})")
    print(f"sigma_xx = {sigma_xx[-1]:.4f}, sigma_yy = {sigma_yy[-1]:.4f} Pa "
          f"(walls {sigma_xx_walls[-1]:.4f}, {sigma_yy_walls[-1]:.4f}); periodic cell "
          f"{bulk_stress[-1, 0, 0]:.4f}, {bulk_stress[-1, 1, 1]:.4f} Pa, sigma_zz "
          f"{bulk_stress[-1, 2, 2]:.4f} Pa")
    out = figure_path("ex02_uniaxial_compression.png",
                      Path(os.environ.get("EXAMPLES_OUTPUT", "output")) / "ex02",
                      Path(__file__).resolve().parents[1] / "docs" / "figures")
    out.parent.mkdir(parents=True, exist_ok=True)
    visualize().savefig(out, dpi=90)
    print(f"figure: {out}")
