"""A 3D cantilever made of a cubic lattice of rigid bodies joined by beams (Fig 11).

A bar 1 m long with a 0.1 m square section (E = 1 GPa, density 1000 kg/m^3) is filled
with an ``n x n`` grid of bodies per cross-section and ``10 n + 1`` layers along its
length (:func:`lattice_cantilever`), clamped at x = 0 and loaded by a uniform
acceleration along -z that sags an Euler-Bernoulli bar by ``L / 1000``. Two lattices:

- ``"nearest"``: bonds to the 6 nearest neighbours, each carrying its tributary
  section; the lattice has the bar's EA and EI exactly and is, in bulk, an isotropic
  solid with ``nu = 0`` and ``G = E / 2``;
- ``"radius"``: bonds to every body within ``r = 1.8 s`` (the 26 neighbours of the
  3 x 3 x 3 stencil; the paper's r = 0.06 m at n = 3), one common section calibrated
  so that the bulk lattice has Young's modulus E.

Dynamic relaxation finds the static state; the deflection is the mean over the tip
layer. Claims checked by tests/dem/test_beam_lattice.py (``main(small=True)``, a 0.5 m
bar): the nearest-neighbour lattice's deflection approaches the continuum bar's
(Euler-Bernoulli plus the shear deflection of its ``G = E / 2``), and the error of
both lattices falls as bodies are added; the radius lattice is far too soft at coarse
resolution because its surface bodies miss bonds (the peridynamic surface effect).
"""

import os
from pathlib import Path

from dem.io.hdf5 import figure_path
from dem.peridynamics.beam_lattice import lattice_constants, lattice_deflection
from dem.peridynamics.beams import cantilever_theory

SIDE, YOUNG, DENSITY = 0.1, 1e9, 1000.0  # [m], [Pa], [kg/m^3]
SAG = 1e-3  # Euler-Bernoulli tip deflection / length
RATIO = 1.8  # bond radius / spacing of the "radius" lattice
KAPPA = 5.0 / 6.0  # shear coefficient of a rectangle
FULL = {"length": 1.0, "sections": (2, 3, 4, 5)}
SMALL = {"length": 0.5, "sections": (2, 3)}
DOCS = Path(__file__).resolve().parents[1] / "docs" / "figures"
#: the figure: in the output folder, or in docs/figures/ when run with --docs
FIGURE = figure_path("beams_lattice.png",
                     Path(os.environ.get("EXAMPLES_OUTPUT", "output")) / "beams_lattice", DOCS)


def shear_modulus(variant):
    """Bulk shear modulus [Pa] of the lattice (``C44`` at the calibrated section)."""
    c = lattice_constants(1.0 if variant == "nearest" else RATIO)
    return YOUNG * c.c44 / c.young


def sweep(length, sections):
    """``{variant: {n: row}}``: each row holds the body and bond counts, relaxation
    steps, tip deflection ``w`` [m] and its relative errors against Euler-Bernoulli
    (``eb``) and against Euler-Bernoulli plus the lattice's shear deflection
    ``rho a L^2 / (2 kappa G)`` (``timoshenko``)."""
    accel = SAG * length / cantilever_theory(length, SIDE, YOUNG, DENSITY, 1.0)
    w_eb = cantilever_theory(length, SIDE, YOUNG, DENSITY, accel)
    table = {}
    for variant in ("nearest", "radius"):
        shear = DENSITY * accel * length**2 / (2.0 * KAPPA * shear_modulus(variant))
        w_t = w_eb + shear
        rows = table[variant] = {}
        for n in sections:
            s = SIDE / n
            n_x = round(length / s) + 1
            radius = None if variant == "nearest" else RATIO * s
            w, sim = lattice_deflection(n_x, n, n, length, SIDE, SIDE, YOUNG, DENSITY,
                                        accel, radius=radius)
            rows[n] = {"bodies": sim.bodies.n, "bonds": sim.bonds.n_bonds,
                       "steps": sim.step, "w": w, "eb": w / w_eb - 1.0,
                       "timoshenko": w / w_t - 1.0}
    return table


def visualize(table):
    """Relative error of the tip deflection against the number of bodies."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4.0))
    styles = {"nearest": ("o", "nearest neighbours"),
              "radius": ("s", f"all within r = {RATIO} s")}
    for color, (variant, rows) in enumerate(table.items()):
        ns = sorted(rows)
        bodies = [rows[n]["bodies"] for n in ns]
        style, label = styles[variant]
        ax.loglog(bodies, [abs(rows[n]["eb"]) for n in ns], marker=style, ls="-",
                  color=f"C{color}", label=f"{label}, vs Euler-Bernoulli")
        ax.loglog(bodies, [abs(rows[n]["timoshenko"]) for n in ns], marker=style,
                  mfc="none", ls="--", color=f"C{color}",
                  label=f"{label}, vs EB + shear")
        for n, b in zip(ns, bodies, strict=True):
            ax.annotate(f"{n}x{n}", (b, abs(rows[n]["eb"])), fontsize=7,
                        textcoords="offset points", xytext=(3, 3))
    ax.set_xlabel("bodies")
    ax.set_ylabel("|relative error| of the tip deflection")
    ax.set_title("3D lattice cantilever (cross-section n x n)")
    ax.legend(frameon=False, fontsize=7)
    fig.tight_layout()
    return fig


def main(small=False, out=FIGURE):
    """Run the sweep, write the figure to ``out`` and return the table of
    :func:`sweep`."""
    from dem.io.hdf5 import save_figure

    size = SMALL if small else FULL
    table = sweep(size["length"], size["sections"])
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    save_figure(visualize(table), out)
    return table


if __name__ == "__main__":
    table = main()
    for variant in table:
        print(f"{variant}: G = {shear_modulus(variant):.4g} Pa")
    print("variant  section  bodies  bonds   steps   w [m]       err EB     "
          "err EB+shear")
    for variant, rows in table.items():
        for n, r in rows.items():
            print(f"{variant:8s} {n}x{n}     {r['bodies']:6d} {r['bonds']:6d} "
                  f"{r['steps']:7d}  {r['w']:.5e}  {r['eb']:+.3e}  "
                  f"{r['timoshenko']:+.3e}")
    print(f"figure: {FIGURE}")
