"""Stress concentration at a circular hole (Kirsch) with the linear peridynamic solid:
convergence as the horizon and the lattice spacing shrink.

A square plate (side 1 m, hole radius 0.1 m, plane stress, nu = 0.3) is stretched by
1e-4 between grips a horizon deep at its top and bottom, starting from the homogeneous
uniaxial-stress field, and relaxed (local damping) to equilibrium. The stress of each
point is the classical stress of its nonlocal deformation gradient (``PDSimulation.stress``).
Two estimates of the concentration factor sigma_yy(hole edge) / sigma_far:

- ``nearest``: the largest sigma_yy among the points next to the hole on its horizontal
  diameter: what a reader of the point data sees, smoothed over a horizon;
- ``fitted``: the Kirsch profile ``1 + A (a^2 / 2 r^2 + 3 a^4 / 2 r^4) / 2`` fitted, by
  least squares in A, to the points of that diameter more than a horizon from the hole
  (where the nonlocal smoothing has faded), and evaluated at the edge.

Kirsch's infinite plate gives 3; this plate's width (hole diameter / width = 0.2) raises
it to about 3.14 (Peterson's chart). Writes benchmarks/results/pd_kirsch.json and
docs/figures/pd_kirsch.png. Run: python benchmarks/pd_kirsch.py [--quick]
"""

import json
import sys
import time
from pathlib import Path

import numpy as np

import dem
from dem import peridynamics as pd
from dem.io.hdf5 import save_figure

WIDTH, RADIUS, STRAIN = 1.0, 0.1, 1e-4
KIRSCH, FINITE_WIDTH = 3.0, 3.14


def kirsch_shape(r, a):
    return 0.5 * (a**2 / (2 * r**2) + 3 * a**4 / (2 * r**4))


def concentration(dx, m, corrected=True, scale=1.0, max_steps=40000, threads=None,
                  settle=1e-4):
    """(nearest, fitted, steps, points) for lattice spacing dx and horizon m dx on a plate
    of side ``scale`` (hole and plate scaled together), relaxed until the point stress
    next to the hole changes by less than ``settle`` per 100 steps."""
    W, a, dx = WIDTH * scale, RADIUS * scale, dx * scale
    c = 0.5 * W
    b = dem.Bodies.empty(2)
    ids = pd.add_points(b, pd.lattice([0, 0], [W, W], dx,
                                      keep=lambda x: ((x - c) ** 2).sum(1) > a * a),
                        dx, 1000.0, thickness=0.01)
    mat = pd.LPS(E=1e9, nu=0.3, density=1000.0, plane="stress",
                 surface_correction=corrected)
    sim = pd.PDSimulation(b, mat, ids, m * dx, damping=0.5, threads=threads)
    x, y = sim.x0.T
    grips = np.flatnonzero((y > y.max() - sim.horizon) | (y < y.min() + sim.horizon))
    b.pos[:, 0] = x - mat.nu * STRAIN * (x - c)
    b.pos[:, 1] = y + STRAIN * (y - c)
    b.fix(grips, [0.0, 0.0])
    row = np.abs(y - c) < 0.51 * dx                     # the horizontal diameter
    far = (np.abs(y - c - 0.3 * W) < 0.51 * dx) & (x > sim.horizon) & (x < W - sim.horizon)
    r = np.abs(x - c)
    prev = None
    while sim.step < max_steps:
        sim.run(100)
        s = sim.stress()[:, 1, 1] / sim.stress()[far, 1, 1].mean()
        nearest = float(s[row & (r < a + dx)].max())
        if prev is not None and abs(nearest - prev) < settle:
            break
        prev = nearest
    fit = row & (r > a + sim.horizon) & (r < 2 * a + sim.horizon) & (x > sim.horizon) & (
        x < W - sim.horizon)
    f = kirsch_shape(r[fit], a)
    amp = float(((s[fit] - 1.0) * f).sum() / (f * f).sum())
    fitted = 1.0 + amp * kirsch_shape(a, a)
    return nearest, fitted, sim.step, int(ids.size)


def main(quick=False):
    rows = []
    # delta-convergence at m = 3; m-convergence at delta = 0.04 m (spacings that divide
    # the plate's side, so every lattice is centred on the hole)
    runs = [(0.02, 3.0), (0.0125, 3.0), (0.01, 3.0)] if quick else [
        (0.02, 3.0), (0.01, 3.0), (0.005, 3.0), (0.02, 2.0), (0.01, 4.0), (0.008, 5.0)]
    for dx, m in runs:
        t = time.perf_counter()
        nearest, fitted, steps, n = concentration(dx, m)
        rows.append({"dx": dx, "m": m, "horizon": m * dx, "nearest": nearest,
                     "fitted": fitted, "steps": steps, "points": n,
                     "seconds": time.perf_counter() - t})
        print(f"dx {dx:.4f} m, m {m:.0f}: nearest {nearest:.3f}, fitted {fitted:.3f} "
              f"({n} points, {steps} steps)")
    root = Path(__file__).resolve().parents[1]
    out = root / "benchmarks" / "results" / "pd_kirsch.json"
    out.write_text(json.dumps({"kirsch": KIRSCH, "finite_width": FINITE_WIDTH,
                               "rows": rows}, indent=1))
    plot(rows, root / "docs" / "figures" / "pd_kirsch.png")
    print(f"wrote {out}")


def plot(rows, path):
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(9, 3.6))
    for ax, key, label in ((left, "m", "m = 3: shrinking dx and delta together"),
                           (right, "delta", "delta = 0.04 m: growing m = delta / dx")):
        sel = [r for r in rows if (r["m"] == 3.0 if key == "m" else
                                   abs(r["horizon"] - 0.04) < 1e-9)]
        sel.sort(key=lambda r: r["horizon"] if key == "m" else r["m"])
        xs = [r["horizon"] if key == "m" else r["m"] for r in sel]
        for est, mark in (("nearest", "o-"), ("fitted", "s--")):
            ax.plot(xs, [abs(r[est] / FINITE_WIDTH - 1) for r in sel], mark, label=est)
        ax.set_title(label, fontsize=9)
        ax.set_xlabel("horizon delta [m]" if key == "m" else "m")
        ax.set_ylabel("|K / 3.14 - 1|")
        ax.set_yscale("log")
        ax.legend()
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)


if __name__ == "__main__":
    main(quick="--quick" in sys.argv)
