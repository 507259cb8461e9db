"""A plate with an elliptical hole breaks in two, and its halves collide (paper Fig 9).

A glass-like plate 1 m x 1 m x 1 cm (plane stress, linear peridynamic solid, 125 x 125
points at full size) with a central elliptical hole, semi-axes 5 cm across and 15 cm
along the plate's height, is pulled apart by body forces on strips a horizon wide at
its left and right edges. The load rises linearly (the profile of eq 37,
``b(t) = b0 t / t_r``), slowly: the grips' own stress would reach the critical stretch
only at ``t_r = 5 T_RAMP``, some fifty times the time a wave takes to cross the plate.
Once the plate has split, the load is reversed and drives the two halves back into each
other, where they meet as DEM bodies.

Claims checked (``tests/test_examples.py::test_pd_plate_*``):

- fracture starts at the hole's top and bottom, where the stress concentrates (the
  first broken bonds lie within a horizon of the ends of the hole's long axis);
- the cracks run to the plate's top and bottom edges and part it in two halves;
- after the load is reversed, the halves collide through contact: they stop closing
  and never overlap by more than a fifth of the lattice spacing.

Run ``python examples/pd_plate_hole.py`` (31 x 31 points, seconds) or with
``EXAMPLES_SIZE=full`` (125 x 125 points, minutes). It writes
``output/pd_plate_hole/plate.h5`` + ``.xdmf`` (points with their damage, for ParaView)
and ``pd_plate_hole.png`` beside them (damage and force density at five instants;
into ``docs/figures/`` with ``--docs``).
"""

import os
from pathlib import Path

import numpy as np

import dem
from dem import peridynamics as pd
from dem.io import H5Writer
from dem.io.hdf5 import figure_path, save_figure

SIZE = os.environ.get("EXAMPLES_SIZE", "small")

WIDTH, THICKNESS = 1.0, 0.01                 # [m]
HOLE = (0.05, 0.15)                          # semi-axes along x and y [m]
E, NU, RHO, G0 = 72e9, 0.22, 2440.0, 3.8     # glass-like [Pa], [-], [kg/m^3], [J/m^2]
T_RAMP = 2e-3                                # [s], see build()
REVERSE = 0.25                               # reversed load, fraction of the breaking one


def build(n):
    """The plate of n x n points, its grip strips and the simulation."""
    dx = WIDTH / n
    c = 0.5 * WIDTH

    def outside_hole(x):
        return ((x[:, 0] - c) / HOLE[0]) ** 2 + ((x[:, 1] - c) / HOLE[1]) ** 2 > 1.0

    bodies = dem.Bodies.empty(2)
    ids = pd.add_points(bodies, pd.lattice([0, 0], [WIDTH, WIDTH], dx, keep=outside_hole),
                        dx, RHO, thickness=THICKNESS)
    material = pd.LPS(E=E, nu=NU, density=RHO, plane="stress", G0=G0,
                      surface_correction=True)
    sim = pd.PDSimulation(bodies, material, ids, horizon=3 * dx)
    x = sim.x0[:, 0]
    left = np.flatnonzero(x < sim.horizon)
    right = np.flatnonzero(x > WIDTH - sim.horizon)
    strip = left.size / n * dx  # width of a grip strip [m]
    b0 = E * material.critical_stretch(2, sim.horizon) / strip  # [N/m^3]
    sim.add_body_force(left, [-b0, 0.0])
    sim.add_body_force(right, [b0, 0.0])
    sim.set_profile([0.0, 5 * T_RAMP], [0.0, 1.0])
    return sim, left, right


def fragments(sim):
    """Label of each point's fragment (connected by intact bonds), largest first."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    f = sim.family
    keep = f.broken == 0
    n = sim.bodies.n
    graph = coo_matrix((np.ones(int(keep.sum())), (f.owner()[keep], f.nbr[keep])),
                       shape=(n, n))
    _, label = connected_components(graph, directed=False)
    order = np.argsort(-np.bincount(label))
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return rank[label]


def split(sim):
    """Whether the two largest fragments each hold a third of the points."""
    sizes = np.bincount(fragments(sim))
    return sizes.size > 1 and sizes[1] > sim.bodies.n / 3


def run(n=125, out="output/pd_plate_hole", figure=None):
    """Load, split, reverse, collide; returns a dict of what the claims need."""
    sim, _, _ = build(n)
    dx = sim.dx
    first_broken = None
    frames = []
    os.makedirs(out, exist_ok=True)
    writer = H5Writer(Path(out) / "plate.h5", every=10**9, contacts=False,
                      fields={"damage": (lambda s: s.damage(), "1")})
    chunk = max(1, int(0.05 * T_RAMP / sim.dt))

    def snap(label):
        frames.append((label, sim.bodies.pos.copy(), sim.damage(),
                       np.linalg.norm(sim.bodies.force, axis=1) / np.maximum(sim.vol, 1e-300)))
        writer(sim)

    snap("t = 0")
    # load until the plate has split (or a generous time limit)
    while not split(sim) and sim.time < 5 * T_RAMP:
        sim.run(chunk)
        if first_broken is None and sim.family.broken.any():
            first_broken = sim.x0[sim.family.owner()[sim.family.broken > 0]]
            snap(f"first damage, t = {sim.time * 1e3:.2f} ms")
    snap(f"split, t = {sim.time * 1e3:.2f} ms")
    t_split = sim.time
    # reverse the load: the halves are driven back together
    level = t_split / (5 * T_RAMP)
    sim.set_profile([t_split, t_split + 0.05 * T_RAMP], [level, -REVERSE * level])
    gaps = []
    label = fragments(sim)
    lhs, rhs = np.flatnonzero(label == 0), np.flatnonzero(label == 1)
    after = None  # chunks left once the halves touch (contact distance: dx)
    while (after is None or after > 0) and len(gaps) < 400:
        sim.run(chunk)
        gaps.append(_min_gap(sim.bodies.pos[lhs], sim.bodies.pos[rhs]))
        if after is None and gaps[-1] < dx:
            after = 40
            snap(f"halves meet, t = {sim.time * 1e3:.2f} ms")
        elif after is not None:
            after -= 1
    snap(f"after the impact, t = {sim.time * 1e3:.2f} ms")
    writer.close()
    if figure:
        plot(frames, dx, figure)
    return {"sim": sim, "dx": dx, "first_broken": first_broken,
            "split": t_split < 5 * T_RAMP, "gaps": np.array(gaps), "t_split": t_split}


def _min_gap(a, b):
    """Smallest distance between two point sets (a k-d tree)."""
    from scipy.spatial import cKDTree

    return float(cKDTree(b).query(a, k=1)[0].min())


#: damage [-]: intact points light grey, broken ones dark red
DAMAGE_COLOURS = ("0.85", "#fdae61", "#d7301f", "#67000d")


def figure(frames, dx):
    """Damage (top row) and force density (bottom row) at each frame
    ``(title, pos [m], damage [-], force density [N/m^3])``; every panel at the same
    scale, one colour bar per row. Returns the figure."""
    import matplotlib.pyplot as plt
    from matplotlib.colors import LinearSegmentedColormap, LogNorm

    pos = np.concatenate([f[1] for f in frames])
    lo, hi = pos.min(axis=0) - dx, pos.max(axis=0) + dx
    fig, axes = plt.subplots(2, len(frames), figsize=(3.2 * len(frames), 6.4),
                             sharex=True, sharey=True, squeeze=False, layout="compressed")
    damage_map = LinearSegmentedColormap.from_list("damage", DAMAGE_COLOURS)
    fmax = max(float(f[3].max()) for f in frames)
    fnorm = LogNorm(vmin=1e-4 * fmax, vmax=fmax) if fmax > 0 else LogNorm(1.0, 10.0)
    rows = []
    for k, (label, p, damage, fdens) in enumerate(frames):
        top, bottom = axes[0, k], axes[1, k]
        rows.append((
            top.scatter(p[:, 0], p[:, 1], c=damage, cmap=damage_map, vmin=0.0, vmax=1.0,
                        marker="s", linewidths=0),
            bottom.scatter(p[:, 0], p[:, 1], c=np.maximum(fdens, fnorm.vmin), norm=fnorm,
                           cmap="viridis", marker="s", linewidths=0)))
        top.set_title(label, fontsize=9)
        for ax in (top, bottom):
            ax.set(xlim=(lo[0], hi[0]), ylim=(lo[1], hi[1]), aspect="equal")
            ax.grid(False)
        bottom.set_xlabel("x [m]")
    for ax in axes[:, 0]:
        ax.set_ylabel("y [m]")
    fig.colorbar(rows[0][0], ax=axes[0, :], label="damage [-]", shrink=0.9)
    fig.colorbar(rows[0][1], ax=axes[1, :], label="force density [N/m^3]", shrink=0.9,
                 extend="min")
    _cell_markers(fig, axes, [c for row in rows for c in row], dx)
    return fig


def _cell_markers(fig, axes, scatters, dx):
    """Square markers one lattice cell wide (a little more, so that no seams show)
    at the size the laid-out panels draw a metre."""
    fig.draw_without_rendering()  # lays the panels out
    ax = axes[0, 0]
    box = ax.get_window_extent()
    points_per_m = box.width / fig.dpi * 72.0 / np.diff(ax.get_xlim())[0]
    for c in scatters:
        c.set_sizes([(1.15 * dx * points_per_m) ** 2])


def plot(frames, dx, path):
    """Write :func:`figure` as a PNG to ``path``."""
    import matplotlib.pyplot as plt

    fig = figure(frames, dx)
    save_figure(fig, path)
    plt.close(fig)


def main():
    n = 125 if SIZE == "full" else 31
    out = "output/pd_plate_hole"
    res = run(n, out, figure_path("pd_plate_hole.png", out,
                                  Path(__file__).resolve().parents[1] / "docs" / "figures"))
    fb = res["first_broken"]
    print(f"{n} x {n} points, dx = {res['dx'] * 1e3:.1f} mm, dt = {res['sim'].dt:.3g} s")
    if fb is not None:
        print(f"first damage at y = {np.unique(np.round(fb[:, 1], 3))} m "
              f"(hole tips at {0.5 - HOLE[1]:.2f} and {0.5 + HOLE[1]:.2f} m)")
    print(f"split: {res['split']} at {res['t_split'] * 1e3:.2f} ms; smallest gap between "
          f"the halves afterwards {res['gaps'].min() / res['dx']:.2f} dx")


if __name__ == "__main__":
    main()
