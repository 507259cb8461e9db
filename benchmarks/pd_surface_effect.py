"""The peridynamic surface effect: a free LPS bar pulled at both ends, with and without
the surface correction, against sigma L / E.

Writes benchmarks/results/pd_surface_effect.json. Run: python benchmarks/pd_surface_effect.py
"""

import json
from pathlib import Path

import numpy as np

import dem
from dem import peridynamics as pd

E, RHO, SIG, DX, LENGTH = 1e9, 1000.0, 1e5, 0.01, 0.5


def middle_stretch_ratio(width, corrected, threads=None):
    """Elongation of the bar's middle half over sigma L / E (1 is exact)."""
    b = dem.Bodies.empty(2)
    ids = pd.add_points(b, pd.lattice([0, 0], [LENGTH, width], DX), DX, RHO, thickness=0.01)
    mat = pd.LPS(E=E, nu=0.3, density=RHO, plane="stress", surface_correction=corrected)
    sim = pd.PDSimulation(b, mat, ids, 3 * DX, damping=0.7, threads=threads)
    x = sim.x0[:, 0]
    sim.add_body_force(np.flatnonzero(x > LENGTH - DX), [SIG / DX, 0.0])
    sim.add_body_force(np.flatnonzero(x < DX), [-SIG / DX, 0.0])
    sim.run(1500)
    cols = np.unique(x)
    x1, x2 = cols[len(cols) // 4], cols[3 * len(cols) // 4]
    u = b.pos[:, 0] - x
    return float((u[x == x2].mean() - u[x == x1].mean()) / (SIG * (x2 - x1) / E))


def main():
    rows = []
    for width in (0.1, 0.2, 0.3):
        row = {"width": width, "uncorrected": middle_stretch_ratio(width, False),
               "corrected": middle_stretch_ratio(width, True)}
        rows.append(row)
        print(f"width {width:.1f} m: uncorrected {row['uncorrected']:.3f}, "
              f"corrected {row['corrected']:.3f}")
    out = Path(__file__).parent / "results" / "pd_surface_effect.json"
    out.write_text(json.dumps({"dx": DX, "horizon": 3 * DX, "rows": rows}, indent=1))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
