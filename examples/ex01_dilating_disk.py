"""A dilating disk pushes its hex-packed neighbours outward (paper Fig 6).

Twenty-five equal disks (radius 0.5 m) sit touching on a hexagonal lattice: a centre
disk, its six first neighbours, the twelve disks of the second ring and the six corners
of the third ring, so the cluster has the full six-fold symmetry of the lattice. The
centre disk grows at ``dR/dt = 1 m/s``, a :class:`dem.SphereRadius` state object
advanced by RK2 (paper eq 21); its mass follows the radius at constant density.
Contacts follow the paper's elastic law (kn = 20 N/m, ks = kn / 2, mu = 0.3). There is
no gravity, no wall and no damping.

The density, 1e-3 kg/m^2 (mass per unit thickness), makes the contact response time
``sqrt(m / kn)`` of about 6 ms eighty times shorter than the growth time
``R0 / (dR/dt) = 0.5 s``, so contacts stay shallow (under 2 % of the radius). The run is
not quasi-static, and cannot be: nothing holds the cluster together, so a neighbour
hit by a surface moving at 1 m/s rebounds elastically at up to 2 m/s and keeps going.
Cundall local damping (``damping=0.7``) changes the first neighbours' displacement by
only 5 % and makes total momentum vanish by symmetry instead of by action and reaction,
so it is left off. The time step is the default, ``dem.DT_FACTOR * sim.dt_crit``.

Claims checked by tests/test_examples.py:

- the centre radius grows exactly linearly, ``R(t) = R0 + t`` (RK2 is exact for a
  constant rate);
- the six first neighbours move radially outward, all by the same distance, and at
  least as far as the surface of the centre disk moved, less an elastic overlap;
- every other disk moves away from the centre too, and the whole displacement field is
  six-fold symmetric: turning the cluster by 60 degrees turns its displacement field;
- total linear momentum stays zero: no wall acts, and contact forces come in
  action-reaction pairs.

``EXAMPLES_SIZE=full`` runs until the radius has doubled (0.5 s) instead of grown by
half (0.25 s).
"""

import os
from pathlib import Path

import numpy as np

import dem
from dem.io.hdf5 import figure_path

SIZE = os.environ.get("EXAMPLES_SIZE", "small")

R0 = 0.5  # initial radius of every disk [m]
DENSITY = 1.0e-3  # [kg/m^2], mass per unit thickness
GROWTH_RATE = 1.0  # dR/dt of the centre disk [m/s]
T_END = {"small": 0.25, "full": 0.5}[SIZE]  # [s]
N_RECORDS = 50


def hex_cluster(radius):
    """Centres (25, 2) [m] of a six-fold symmetric cluster of touching disks.

    Rows are ordered by ring (centre, 6 first neighbours, 12 second-ring disks, 6
    corners of the third ring) and by polar angle within a ring; row 0 is the centre.
    """
    a1 = np.array([2.0 * radius, 0.0])
    a2 = np.array([radius, np.sqrt(3.0) * radius])
    rows = []
    for i in range(-3, 4):
        for j in range(-3, 4):
            k = -i - j
            ring = max(abs(i), abs(j), abs(k))
            is_corner = sorted((abs(i), abs(j), abs(k))) == [0, 3, 3]
            if ring <= 2 or is_corner:
                x = i * a1 + j * a2
                angle = np.arctan2(x[1], x[0]) % (2.0 * np.pi)
                rows.append((ring, round(angle, 9), x))
    rows.sort(key=lambda r: r[:2])
    return np.array([r[2] for r in rows])


def rotation(angle):
    """2D rotation matrix (2, 2) by ``angle`` [rad]."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


pos0 = hex_cluster(R0)
MID = 0
FIRST_RING = np.arange(1, 7)
bodies = dem.Bodies.spheres(pos0, radius=R0, density=DENSITY)

grow = dem.SphereRadius(ids=[MID], rate=lambda r, t: GROWTH_RATE * np.ones_like(r))
law = dem.Elastic(kn=20.0, kt=10.0, mu=0.3)
dt_crit = dem.critical_time_step(bodies, dem.ContactModel(law))[0]
dt = dem.DT_FACTOR * dt_crit  # the default time step, needed here to size the run
n_steps = int(round(T_END / dt))
every = max(1, n_steps // N_RECORDS)
n_steps -= n_steps % every  # the last record is the final state
tracker = dem.ParticleTracker(np.arange(bodies.n), every=every)
radius_log = dem.Record(lambda sim: float(sim.bodies.radius[MID]), every=every)
momentum_log = dem.Record(
    lambda sim: (sim.bodies.mass[:, None] * sim.bodies.vel).sum(axis=0), every=every)
sim = dem.Simulation(bodies, law, dt=dt, state_objects=[grow],
                     observers=[tracker, radius_log, momentum_log])
sim.run(n_steps)

# ---------------------------------------------------------------- results
times = np.array(radius_log.times)  # [s]
radius_mid = np.array(radius_log.values)  # [m]
radius_theory = R0 + GROWTH_RATE * times
growth = radius_mid[-1] - R0  # how far the centre disk's surface moved [m]

track = tracker.as_arrays()
disp = track["pos"] - pos0[None]  # (n_records, 25, 2) displacement [m]
u = disp[-1]
e_r = pos0[FIRST_RING] / np.linalg.norm(pos0[FIRST_RING], axis=1)[:, None]
u_radial_first = np.einsum("ia,ia->i", u[FIRST_RING], e_r)  # outward displacement [m]
u_norm_first = np.linalg.norm(u[FIRST_RING], axis=1)
radial_history = np.einsum("tia,ia->ti", disp[:, FIRST_RING], e_r)  # (n_records, 6)

# overlap of the centre disk with its first neighbours at the end [m]
gap_vec = track["pos"][-1, FIRST_RING] - track["pos"][-1, MID]
overlap_first = radius_mid[-1] + R0 - np.linalg.norm(gap_vec, axis=1)

# six-fold symmetry: disk q sits where a 60-degree turn takes disk p
Q60 = rotation(np.pi / 3.0)
turned = pos0 @ Q60.T
image = np.argmin(np.linalg.norm(turned[:, None] - pos0[None], axis=2), axis=1)
symmetry_error = np.abs(u[image] - u @ Q60.T).max() / np.abs(u).max()
outward = np.einsum("pa,pa->p", u, pos0)  # > 0: disk p moved away from the centre

momentum = np.array(momentum_log.values)  # (n_records, 2) [kg m/s]
momentum_scale = np.max(
    np.sum(bodies.mass[None, :] * np.linalg.norm(track["vel"], axis=2), axis=1))


def visualize():
    """Displacement field (left) and centre radius and neighbour motion (right)."""
    import matplotlib.pyplot as plt
    from matplotlib.collections import PatchCollection
    from matplotlib.patches import Circle

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 4.4))
    final = track["pos"][-1]
    radii = bodies.radius
    u_norm = np.linalg.norm(u, axis=1)
    ax.add_collection(PatchCollection(
        [Circle(x, R0) for x in pos0], facecolor="none", edgecolor="0.6",
        linestyle="--", linewidth=0.8))
    disks = PatchCollection([Circle(x, r) for x, r in zip(final, radii, strict=True)],
                            cmap="viridis", edgecolor="k", linewidth=0.6, alpha=0.85)
    disks.set_array(u_norm)
    ax.add_collection(disks)
    ax.quiver(pos0[:, 0], pos0[:, 1], u[:, 0], u[:, 1], angles="xy", scale_units="xy",
              scale=1.0, width=0.004, color="crimson")
    fig.colorbar(disks, ax=ax, label="|displacement| [m]", shrink=0.8)
    lim = np.abs(final).max() + radii.max() + 0.2
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"t = {times[-1]:.2f} s: start (dashed), now (filled)")

    bx.plot(times, radius_mid - R0, "o", ms=3, label="centre R - R0")
    bx.plot(times, radius_theory - R0, "k-", lw=1, label="(dR/dt) t")
    bx.plot(times, radial_history.mean(axis=1), "-", color="crimson",
            label="first ring, radial displacement")
    bx.set_xlabel("t [s]")
    bx.set_ylabel("growth, displacement [m]")
    bx.set_title("centre disk growth and first-ring motion")
    bx.legend(frameon=False)
    fig.tight_layout()
    return fig


if __name__ == "__main__":
    print(f"{SIZE}: {n_steps} steps of dt = {dt:.3e} s (dt_crit = {sim.dt_crit:.3e} s)")
    print(f"centre radius {radius_mid[-1]:.6f} m, R0 + t = {radius_theory[-1]:.6f} m")
    print(f"first ring radial displacement {u_radial_first.round(6)} m "
          f"(centre surface moved {growth:.4f} m)")
    print(f"six-fold symmetry error {symmetry_error:.1e}, "
          f"max |momentum| {np.abs(momentum).max():.1e} kg m/s")
    out = figure_path("ex01_dilating_disk.png",
                      Path(os.environ.get("EXAMPLES_OUTPUT", "output")) / "ex01",
                      Path(__file__).resolve().parents[1] / "docs" / "figures")
    out.parent.mkdir(parents=True, exist_ok=True)
    visualize().savefig(out, dpi=90)
    print(f"figure: {out}")
