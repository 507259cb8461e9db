"""The paper's compression (Figs 7 and 8) through the two RVE interfaces: a box of walls
against a periodic cell.

The spheres of ``ex02_uniaxial_compression.py`` -- radius 0.5 m, hexagonal close packed
(HCP, ABAB layers along z), every sphere touching its neighbours, the paper's
viscoelastic law (kn = 20 N/m, ks = kn / 2, gamma_n = 0.08 N s/m, gamma_s = gamma_n / 2,
mu = 0.3) -- are compressed along z with no lateral strain (oedometric loading) to 4 %
axial strain, in quasi-static increments of 0.2 %: each imposed at no more than 1e-5
strain per step, then relaxed to an unbalanced-force ratio of 1e-3. Where ex02 moves a
lid at a constant speed, here each increment is a Gauss-point call:

* :class:`dem.rve_box.BoxRVE` -- the paper's box: six planar walls, smooth (no friction
  on the walls, as in ex02), the lid and floor moved by the increment, the side walls
  held;
* :class:`dem.rve.RVE` -- the same layers in a triply periodic cell, deformed by the
  same increments: the bulk crystal, with no walls at all.

Claims checked by tests/test_examples.py:

- in both, the axial stress is compressive and grows with every increment; the box's
  wall stress and its Love-Weber stress over the contacts agree to within the
  relaxation tolerance (equilibrium of the walls and the packing);
- the periodic crystal is transversely isotropic about z: sigma_xx = sigma_yy and the
  shear stresses vanish, to round-off;
- the periodic cell's axial stress follows the affine estimate of the lattice:
  inter-layer contacts (6 per sphere, normals at cos^2 = 2/3 to z) compressed by
  2 r eps cos^2, so ``sigma_zz = -(2 sqrt(2) / 3) (kn + kt / 2) eps / r`` for small
  strain (the tangential springs of the tilted contacts add kt / 2), within 10 %;
- the box is softer than the bulk: its floor and lid act in series with the layers.
  A sphere touches a wall with one contact of stiffness kn along z, where it has three
  inclined ones to the next layer, so the two wall contacts of a column of ``nz``
  layers add the compliance of ``2 A_s / kn`` (``A_s = 2 sqrt(3) r^2`` a sphere's
  share of a layer) to that of its ``nz - 1`` layer gaps, ``(nz - 1) dz / M`` with
  ``M`` the lattice's oedometric modulus: ``sigma_zz = -M_series eps`` with
  ``M_series = H0 / ((nz - 1) dz / M + 2 A_s / kn)``, 0.62 M for 6 layers. The side
  walls soften the box further -- walls cannot close a hexagonal crystal (every
  other row ends a radius short of an x wall, A and B layers touch opposite y walls),
  so the edge rows give way -- and the box's axial stress lies below this estimate,
  within 25 % of it.

Small size: 8 x 8 x 6 spheres (384) in both; ``EXAMPLES_SIZE=full``: 16 x 16 x 12
(3,072) in both.
"""

import os
from pathlib import Path

import numpy as np

import dem
from dem.io.hdf5 import figure_path
from dem.boundary import PeriodicCell
from dem.io.packing import hcp_layers
from dem.rve import RVE
from dem.rve_box import BoxRVE

SIZE = os.environ.get("EXAMPLES_SIZE", "small")

RADIUS = 0.5  # [m]
DENSITY = 1.0e-3  # [kg/m^3]
LAW = dem.Viscoelastic(kn=20.0, kt=10.0, gamma_n=0.08, gamma_t=0.04, mu=0.3)
INCREMENT = 2e-3  # axial strain per call
STRAIN_END = 0.04
BOX_N, CELL_N = {"small": ((8, 8, 6), (8, 8, 6)),
                 "full": ((16, 16, 12), (16, 16, 12))}[SIZE]
SETTINGS = {"damping": 0.5, "tol": 1e-3, "max_step_strain": 1e-5}


def oedometric(rve, n_increments, love=False):
    """Axial strain increments with the lateral axes held: the axial strains and the
    stresses after each, with the start (and with ``love`` the box's Love-Weber
    stresses after each increment)."""
    deps = np.zeros((3, 3))
    deps[2, 2] = -INCREMENT
    strain, stress, love_weber = [0.0], [rve.stress()], []
    for _ in range(n_increments):
        stress.append(rve.apply_strain(deps))
        strain.append(1.0 - rve.deformation[2, 2])
        if love:
            love_weber.append(rve.response(tangent=False)["stress_love"])
    return np.array(strain), np.array(stress), np.array(love_weber)


n_inc = int(round(STRAIN_END / INCREMENT))

# ---------------------------------------------------------------- the box
pos = hcp_layers(*BOX_N, RADIUS)
box_hi = np.array([BOX_N[0] * 2.0 * RADIUS + RADIUS, pos[:, 1].max() + RADIUS,
                   pos[:, 2].max() + RADIUS])
box = BoxRVE(dem.Bodies.spheres(pos, radius=RADIUS, density=DENSITY), LAW,
             lo=[0.0, 0.0, 0.0], hi=box_hi, **SETTINGS)
box_strain, box_stress, box_love = oedometric(box, n_inc, love=True)
box_unbalanced = box.response(tangent=False)["unbalanced"]

# ---------------------------------------------------------------- the periodic cell
cell_size = np.array([CELL_N[0] * 2.0 * RADIUS, CELL_N[1] * np.sqrt(3.0) * RADIUS,
                      CELL_N[2] * 2.0 * np.sqrt(2.0 / 3.0) * RADIUS])
cell_pos = hcp_layers(*CELL_N, RADIUS) % cell_size
cell = RVE(dem.Bodies.spheres(cell_pos, radius=RADIUS, density=DENSITY), LAW,
           PeriodicCell(cell_size), **SETTINGS)
cell_strain, cell_stress, _ = oedometric(cell, n_inc)

#: the lattice's oedometric modulus [Pa] (affine) and the periodic crystal's axial
#: stress [Pa] it gives at each strain
MODULUS = (2.0 * np.sqrt(2.0) / 3.0) * (LAW.kn + 0.5 * LAW.kt) / RADIUS
affine_zz = -MODULUS * cell_strain
#: the box's column: layer gaps and the two wall contacts in series
LAYER_GAP = 2.0 * np.sqrt(2.0 / 3.0) * RADIUS
SPHERE_AREA = 2.0 * np.sqrt(3.0) * RADIUS**2
MODULUS_SERIES = box_hi[2] / ((BOX_N[2] - 1) * LAYER_GAP / MODULUS
                              + 2.0 * SPHERE_AREA / LAW.kn)
series_zz = -MODULUS_SERIES * box_strain


def visualize():
    """Axial and lateral stress against axial strain: box and periodic cell."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    ax.plot(100 * box_strain, -box_stress[:, 2, 2], "o-", color="C0", ms=4,
            label=r"$-\sigma_{zz}$, box (walls)")
    ax.plot(100 * box_strain, -box_stress[:, 0, 0], "s-", color="C1", ms=4,
            label=r"$-\sigma_{xx}$, box")
    ax.plot(100 * box_strain, -box_stress[:, 1, 1], "^-", color="C2", ms=4,
            label=r"$-\sigma_{yy}$, box")
    ax.plot(100 * cell_strain, -cell_stress[:, 2, 2], "k--",
            label=r"$-\sigma_{zz}$, periodic")
    ax.plot(100 * cell_strain, -cell_stress[:, 0, 0], "k:",
            label=r"$-\sigma_{xx} = -\sigma_{yy}$, periodic")
    ax.plot(100 * cell_strain, -affine_zz, color="0.6", lw=0.8,
            label=r"affine lattice estimate of $-\sigma_{zz}$")
    ax.plot(100 * box_strain, -series_zz, color="C0", lw=0.8, ls="-.",
            label=r"lattice and end walls in series, $-\sigma_{zz}$")
    ax.set_xlabel("axial strain [%]")
    ax.set_ylabel("compressive stress [Pa]")
    ax.set_title(f"oedometric compression of HCP spheres: box ({box.particles.size}) "
                 f"and periodic cell ({cell.bodies.n})", fontsize=9)
    ax.legend(frameon=False, fontsize=8)
    fig.tight_layout()
    return fig


if __name__ == "__main__":
    print(f"{SIZE}: box {box.particles.size} spheres, periodic cell {cell.bodies.n}")
    print(f"at {100 * cell_strain[-1]:.1f} % axial strain: sigma_zz box "
          f"{box_stress[-1, 2, 2]:.4f} Pa (Love-Weber {box_love[-1, 2, 2]:.4f}), "
          f"periodic "
          f"{cell_stress[-1, 2, 2]:.4f} (affine {affine_zz[-1]:.4f}), walls in series "
          f"{series_zz[-1]:.4f}; sigma_xx box "
          f"{box_stress[-1, 0, 0]:.4f}, sigma_yy box {box_stress[-1, 1, 1]:.4f}, "
          f"periodic {cell_stress[-1, 0, 0]:.4f}")
    out = figure_path("ex05_box_vs_periodic.png",
                      Path(os.environ.get("EXAMPLES_OUTPUT", "output")) / "ex05",
                      Path(__file__).resolve().parents[1] / "docs" / "figures")
    out.parent.mkdir(parents=True, exist_ok=True)
    visualize().savefig(out, dpi=90)
    print(f"figure: {out}")
