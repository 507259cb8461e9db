"""Demo: pour a few hundred spheres into an open box and let them settle.

``python -m dem.demo [-o DIR] [--overwrite]`` drops spheres from random,
non-overlapping positions into a box of five walls under gravity, with a linear
spring-dashpot law (restitution 0.3) and Coulomb friction, runs until the packing is
near rest and writes

- ``DIR/pour.h5`` and ``DIR/pour.xdmf``: the frames (open the ``.xdmf`` in ParaView);
- ``DIR/pour.png``: kinetic energy against time and a side view of the final packing.

Physical claims (checked by ``tests/dem/test_io.py`` on a small pour): the kinetic
energy at the end is a tiny fraction of the potential energy the fall released, and
every sphere ends inside the box.
"""

import argparse
import logging
import os
import time

import numpy as np

from ._jit import set_threads
from .contact.laws import LinearSpring
from .io import H5Writer
from .io.hdf5 import save_figure
from .observers import kinetic_energy
from .shapes import Shape
from .simulation import Simulation
from .state import Bodies

log = logging.getLogger(__name__)

RADIUS = (0.004, 0.005)  # [m], uniform radius distribution
DENSITY = 2500.0  # [kg/m^3], glass
BOX = 0.08  # [m], inner width of the box
POUR = (0.01, 0.13)  # [m], heights between which the spheres start
GRAVITY = (0.0, 0.0, -9.81)  # [m/s^2]
LAW = {"kn": 1.0e4, "kt": 1.0e4 * 2.0 / 7.0, "mu": 0.5, "restitution": 0.3}
DAMPING = 0.1  # Cundall local damping
REST = 1.0e-4  # near rest: kinetic energy below this fraction of the energy released
N_REST = 5  # ... in this many consecutive records


def random_packing(n, rng, lo, hi, radius, max_tries=200_000):
    """Random sequential addition of ``n`` non-overlapping spheres in a box.

    Parameters
    ----------
    n : int
    rng : numpy.random.Generator
    lo, hi : (3,) array_like [m]
        The box the spheres must lie inside (whole spheres, not only centres).
    radius : (float, float) [m]
        Radii are drawn uniformly between the two values.

    Returns
    -------
    pos : (n, 3) float64 [m]
    r : (n,) float64 [m]
    """
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    r = rng.uniform(radius[0], radius[1], n)
    pos = np.empty((n, 3))
    placed = 0
    for _ in range(max_tries):
        if placed == n:
            break
        ri = r[placed]
        x = rng.uniform(lo + ri, hi - ri)
        if placed:
            gap = np.linalg.norm(pos[:placed] - x, axis=1) - r[:placed] - ri
            if gap.min() <= 0.0:
                continue
        pos[placed] = x
        placed += 1
    if placed < n:
        raise ValueError(f"placed only {placed} of {n} spheres: enlarge the "
                         f"pouring region")
    return pos, r


def make_scene(n_spheres=300, seed=0):
    """Spheres above the floor of an open box of five walls; returns ``Bodies``."""
    rng = np.random.default_rng(seed)
    half = 0.5 * BOX
    pos, r = random_packing(n_spheres, rng, [-half, -half, POUR[0]],
                            [half, half, POUR[1]], RADIUS)
    bodies = Bodies.spheres(pos, radius=r, density=DENSITY)
    bodies.add_plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0])  # floor
    for axis in (0, 1):
        for side in (-1.0, 1.0):
            point = np.zeros(3)
            point[axis] = side * half
            normal = np.zeros(3)
            normal[axis] = -side  # the free side faces the inside of the box
            bodies.add_plane(point, normal)
    return bodies


def run_demo(out_dir="output/demo", n_spheres=300, seed=0, t_max=2.0,
             record_every=0.01):
    """Pour, settle, write ``pour.h5``/``pour.xdmf``; returns a dict of results.

    Parameters
    ----------
    out_dir : str
        Output directory (created if missing).
    n_spheres : int
    seed : int
        Seed of the random pouring positions and radii.
    t_max : float
        Stop after this simulated time [s] even if not at rest.
    record_every : float
        Interval [s] between frames and kinetic energy records.

    Returns
    -------
    dict
        ``sim``, ``times`` [s] and ``kinetic`` [J] (translational + rotational),
        ``released`` [J] (potential energy given up by the fall), ``at_rest``,
        ``h5``/``xdmf`` paths and ``wall_time`` [s].
    """
    bodies = make_scene(n_spheres, seed)
    sim = Simulation(bodies, LinearSpring(**LAW), gravity=GRAVITY, damping=DAMPING)
    free = ~bodies.is_fixed
    g = np.asarray(GRAVITY)

    def potential():
        return -float(np.sum(bodies.mass[free] * (bodies.pos[free] @ g)))

    e_pot0 = potential()
    chunk = max(1, int(round(record_every / sim.dt)))
    h5 = os.path.join(out_dir, "pour.h5")
    times, kinetic = [0.0], [0.0]
    released, at_rest, n_calm = 0.0, False, 0
    start = time.perf_counter()
    config = {"demo": "dem.demo", "n_spheres": n_spheres, "seed": seed, "t_max": t_max}
    with H5Writer(h5, every=chunk, contacts=True, config=config) as writer:
        writer(sim)  # the initial state
        sim.observers.append(writer)
        while sim.time < t_max:
            sim.run(chunk)
            times.append(sim.time)
            kinetic.append(sum(kinetic_energy(bodies)))
            released = e_pot0 - potential()
            calm = released > 0.0 and kinetic[-1] < REST * released
            n_calm = n_calm + 1 if calm else 0
            if n_calm >= N_REST:
                at_rest = True
                break
    wall = time.perf_counter() - start
    log.info("%d spheres, %d steps of %.3g s in %.1f s (at rest: %s)", n_spheres,
             sim.step, sim.dt, wall, at_rest)
    return {"sim": sim, "times": np.array(times), "kinetic": np.array(kinetic),
            "released": released, "at_rest": at_rest, "h5": writer.path,
            "xdmf": writer.xdmf_path, "wall_time": wall}


def visualize(result):
    """Kinetic energy against time and a side view (x-z) of the final packing."""
    from matplotlib.collections import PatchCollection
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle

    sim = result["sim"]
    b = sim.bodies
    sph = np.flatnonzero(b.kind == Shape.SPHERE)
    fig = Figure(figsize=(10, 4), layout="constrained")
    ax1, ax2 = fig.subplots(1, 2)
    t, ke = result["times"][1:], result["kinetic"][1:]
    ax1.semilogy(t, np.maximum(ke, 1e-300))
    ax1.set_xlabel("time t [s]")
    ax1.set_ylabel("kinetic energy [J]")
    ax1.set_title(f"{sph.size} spheres poured into a box")
    ax1.grid(True, which="both", alpha=0.3)
    order = sph[np.argsort(b.pos[sph, 1])]  # back to front
    circles = [Circle((b.pos[i, 0], b.pos[i, 2]), b.radius[i]) for i in order]
    col = PatchCollection(circles, cmap="viridis", edgecolor="k", linewidth=0.3)
    col.set_array(b.pos[order, 1])
    ax2.add_collection(col)
    half = 0.5 * BOX
    ax2.plot([-half, -half, half, half], [POUR[1], 0.0, 0.0, POUR[1]], "k-", lw=2)
    ax2.set_xlim(-1.1 * half, 1.1 * half)
    ax2.set_ylim(-0.005, max(0.5 * POUR[1], float(b.pos[sph, 2].max()) + 0.01))
    ax2.set_aspect("equal")
    ax2.set_xlabel("x [m]")
    ax2.set_ylabel("z [m]")
    ax2.set_title(f"final packing, t = {sim.time:.2f} s (colour: y [m])")
    fig.colorbar(col, ax=ax2, shrink=0.8)
    return fig


def _parser():
    from .cli import Parser, version_line

    parser = Parser(
        prog="python -m dem.demo",
        description="Pour spheres into a box under gravity until they settle; write "
                    "HDF5 + XDMF frames and a PNG summary.",
        epilog="Exit status: 0 done, 2 bad input (bad arguments, existing output "
               "without --overwrite, an output the disk refuses).")
    parser.add_argument("--version", action="version", version=version_line("dem"),
                        help="print the version and exit")
    parser.add_argument("-o", "--output", default=os.path.join("output", "demo"),
                        metavar="DIR", help="output directory (default: %(default)s)")
    parser.add_argument("--out", dest="output", metavar="DIR", default=argparse.SUPPRESS,
                        help=argparse.SUPPRESS)  # deprecated spelling
    parser.add_argument("--overwrite", action="store_true",
                        help="replace existing output files")
    parser.add_argument("--n", type=int, default=300,
                        help="number of spheres (default: %(default)s)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    parser.add_argument("--t-max", type=float, default=2.0,
                        help="longest simulated time [s] (default: %(default)s)")
    parser.add_argument("--threads", type=int, default=1,
                        help="numba threads (default: 1; a scene this small runs "
                             "fastest on one)")
    return parser


def main(argv=None):
    """Command line entry point: ``python -m dem.demo [-o DIR] [--overwrite] [--n N]
    ...``; returns the exit status (0 done, 2 bad input: a bad argument, or an
    existing output without ``--overwrite``). ``--out`` is a deprecated spelling of
    ``--output``."""
    import sys

    from .cli import UsageError, refuse_existing
    from .io.files import OutputError

    def error(msg):
        print("python -m dem.demo: error: " + " ".join(str(msg).split()), file=sys.stderr)
        return 2

    try:
        args = _parser().parse_args(argv)
        if args.n < 1:
            raise UsageError("--n must be at least 1")
        if args.threads < 1:
            raise UsageError("--threads must be at least 1")
    except UsageError as exc:
        return error(exc)
    if argv is None:
        argv = sys.argv[1:]
    if any(a == "--out" or a.startswith("--out=") for a in argv):
        print("python -m dem.demo: warning: --out is deprecated, use -o/--output",
              file=sys.stderr)
    files = [os.path.join(args.output, f) for f in ("pour.h5", "pour.xdmf", "pour.png")]
    try:
        for f in refuse_existing(files, args.overwrite):
            os.remove(f)
    except OSError as exc:
        return error(exc)
    set_threads(args.threads)
    logging.basicConfig(level=logging.WARNING)
    print(f"pouring {args.n} spheres (the first run compiles the kernels) ...")
    png = os.path.join(args.output, "pour.png")
    try:
        result = run_demo(args.output, n_spheres=args.n, seed=args.seed,
                          t_max=args.t_max)
        save_figure(visualize(result), png, dpi=120, data="pour.h5")
    except OutputError as exc:  # the disk refused a file (full, read-only, ...)
        return error(exc)
    sim = result["sim"]
    state = "near rest" if result["at_rest"] else "not yet at rest"
    ke, released = result["kinetic"][-1], result["released"]
    print(f"{sim.step} steps, t = {sim.time:.3f} s simulated in "
          f"{result['wall_time']:.1f} s wall time; {state} "
          f"(KE {ke:.3g} J of {released:.3g} J released)")
    print(f"frames: {result['h5']}")
    print(f"ParaView: {result['xdmf']}")
    print(f"figure: {png}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
