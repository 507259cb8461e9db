"""A cantilever of bonded Euler-Bernoulli beams sags under its own weight.

A bar 1 m long with a 5 cm square section and density 1000 kg/m^3, is
made of ``n`` rigid bodies joined by ``n - 1`` beams (:func:`cantilever`) and clamped at
x = 0. A uniform acceleration ``a`` across it, chosen so that the tip sags by
``L / 1000`` (small deflections), loads it; dynamic relaxation with Cundall damping
finds the static state. Euler-Bernoulli theory gives ``w = M a L^3 / (8 E I)``. The
sweep runs in 2D (plotted) and in 3D (quaternion bodies, the same bar).

Claims checked by tests/dem/test_beams.py (``main(small=True)``):

- the relative error of the tip deflection falls as ``n`` grows, and is under 2 % at
  ``n = 11``;
- it is the same for every Young's modulus (the static answer scales as ``1 / E``)
  and in 2D and 3D;
- it is the lumping error ``1 / (3 (n - 1)^2)`` and nothing else: the beams are exact
  for nodal loads, so the discrete model differs from the continuum only by the
  trapezoidal rule that lumps the weight on the bodies.
"""

import os
from pathlib import Path

import numpy as np

from dem.io.hdf5 import figure_path
from dem.peridynamics.beams import cantilever_deflection, cantilever_theory

LENGTH, HEIGHT, DENSITY = 1.0, 0.05, 1000.0  # [m], [m], [kg/m^3]
SAG = 1e-3  # tip deflection / length
FULL = {"young": (1e6, 1e7, 1e8, 1e9), "n": (3, 5, 11, 21)}
SMALL = {"young": (1e6, 1e9), "n": (3, 5, 11)}
DOCS = Path(__file__).resolve().parents[1] / "docs" / "figures"
#: the figure: in the output folder, or in docs/figures/ when run with --docs
FIGURE = figure_path("beams_cantilever.png",
                     Path(os.environ.get("EXAMPLES_OUTPUT", "output")) / "beams_cantilever", DOCS)


def relative_errors(youngs, ns, dim=2):
    """``{E: {n: (w - w_theory) / w_theory}}`` for the cantilever in ``dim`` D."""
    table = {}
    for young in youngs:
        accel = SAG * LENGTH / cantilever_theory(LENGTH, HEIGHT, young, DENSITY, 1.0)
        exact = cantilever_theory(LENGTH, HEIGHT, young, DENSITY, accel)
        table[young] = {n: cantilever_deflection(dim, n, LENGTH, HEIGHT, young,
                                                 DENSITY, accel)[0] / exact - 1.0
                        for n in ns}
    return table


def visualize(tables):
    """Relative tip-deflection error against the number of bodies, per modulus and
    dimension (``tables`` as returned by :func:`main`)."""
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4.0))
    ns = np.array(sorted(next(iter(tables[2].values()))))
    for dim, fill in ((2, None), (3, "none")):
        for (young, errors), marker in zip(tables[dim].items(), "osd^", strict=False):
            ax.loglog(ns, [errors[n] for n in ns], marker, mfc=fill,
                      ms=5 if fill is None else 9,
                      label=f"{dim}D, E = {young:.0e} Pa")
    fine = np.linspace(ns.min(), ns.max(), 100)
    ax.loglog(fine, 1.0 / (3.0 * (fine - 1.0) ** 2), "k-", lw=1,
              label="lumping error 1/(3 (n-1)^2)")
    ax.axhline(0.02, color="0.6", ls="--", lw=1, label="2 %")
    ax.set_xticks(ns, [str(n) for n in ns])
    ax.xaxis.set_minor_locator(matplotlib.ticker.NullLocator())
    ax.set_xlabel("bodies n")
    ax.set_ylabel("relative error of the tip deflection")
    ax.set_title("cantilever under its own weight")
    ax.legend(frameon=False, fontsize=8, loc="lower left")
    fig.tight_layout()
    return fig


def main(small=False, out=FIGURE):
    """Run the sweep and write the figure to ``out``.

    Returns ``{dim: {E: {n: relative error}}}``.
    """
    from dem.io.hdf5 import save_figure

    sizes = SMALL if small else FULL
    tables = {dim: relative_errors(sizes["young"], sizes["n"], dim) for dim in (2, 3)}
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    save_figure(visualize(tables), out)
    return tables


if __name__ == "__main__":
    tables = main()
    ns = sorted(next(iter(tables[2].values())))
    print("relative error of the tip deflection, (w - w_theory) / w_theory")
    print("dim  E [Pa]" + "".join(f"{f'n = {n}':>12}" for n in ns))
    for dim, table in tables.items():
        for young, errors in table.items():
            print(f"{dim}D  {young:7.0e}" + "".join(f"{errors[n]:12.3e}" for n in ns))
    lumping = {n: 1.0 / (3 * (n - 1) ** 2) for n in ns}
    print("lumping    " + "".join(f"{lumping[n]:12.3e}" for n in ns))
    worst = max(abs((1.0 + errors[n]) / (1.0 + lumping[n]) - 1.0)
                for table in tables.values() for errors in table.values() for n in ns)
    print(f"largest |w / w_n - 1| against the lumped model's exact answer: {worst:.2e}")
    print(f"figure: {FIGURE}")
