"""The angle of repose of a poured pile of spheres rises with rolling friction.

The scene (3D): spheres of mean radius 2 mm (radii uniform within +-15 %, 2500 kg/m^3)
are poured from an insertion box (6 x 6 x 4 mean diameters d, centred on the z axis,
its bottom 2 d above the apex of a 45 deg cone of the same bulk volume at a packing
fraction of 0.6) at rest, 2000 per second (every 0.01 s those due, at random places
where they overlap nothing), onto a rough floor: a square lattice of touching fixed
spheres (radius 2 mm) in a disk of radius 26 d (14 d with ``--quick``), over a plane z
= 0 that catches any particle leaving the floor. The floor's spheres make pockets that
stop the base from spreading; the friction of the pile does the rest. Contacts are
linear spring-dashpots (kn = 5000 N/m, kt = 2/7 kn, restitution 0.5, sliding friction
mu = 0.5) with rolling resistance ``dem.Rolling(mu_roll, eta_roll=0.3)`` for mu_roll
in {0, 0.05, 0.1, 0.2, 0.4}, between the spheres and with the floor alike; gravity
9.81 m/s^2; the engine's default time step for the lightest sphere (1.0e-5 s; 7.9e-6 s
at mu_roll = 0.4, whose rolling spring is stiffer). Full size: 2,000 poured spheres on
2,121 floor spheres (about 2 minutes a case on one core); ``--quick``: 300 on 613,
1000 per second (under 10 s a case). A pile is settled when, after the pour, the
translational kinetic energy of the poured spheres is below ``KE_SETTLED`` = 1e-6 of
``n m g d`` (n spheres of the mean mass m, d the mean diameter), checked every 0.02 s
of simulated time, or at ``T_MAX_AFTER`` = 3 s after the pour (then ``settled`` is
false in the JSON). Spin about the vertical is left out of the criterion: without
twisting resistance a lone sphere on the plane spins on for ever, moving nothing.
Spheres that end more than 25 d (13 d) from the axis rolled off the floor: they are
counted (``n_escaped``) and left out of the criterion and of the measure.

The measure: the settled pile is cut into 8 azimuthal sectors about the pouring axis
and radial bins one mean diameter wide; in every (sector, bin) cell the sphere whose
top (z + r) is highest is the free surface there. The pile's radius R_p is the outer
edge of the last bin, counted out from the axis without a gap, whose median surface
height over the sectors is more than one mean diameter above the tops of the floor's
spheres. A straight line z = a + s r is fitted (least squares) to the surface points
of the bins whose centres lie between 20 % and 80 % of R_p; the angle of repose is
``atan(-s)`` and its uncertainty the slope's standard error mapped through the arc
tangent, ``se(s) / (1 + s^2)``. The 2D (disk) version was not needed: the 3D piles
take minutes.

Writes benchmarks/results/angle_of_repose.json (per mu_roll: the angle and its
uncertainty [deg], the pile radius and height [m], the sphere count, the simulated and
wall-clock time, whether it settled, the median surface profile and the fit) and
docs/figures/angle_of_repose.png.
Run: python benchmarks/angle_of_repose.py [--quick] [--figure]
(``--quick``: 300 spheres, written under benchmarks/work/; ``--figure``: redraw the
figure from the saved JSON without running.)
"""

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

OUT = C.RESULTS / "angle_of_repose.json"
PNG = C.REPO / "docs" / "figures" / "angle_of_repose.png"
MU_ROLLS = (0.0, 0.05, 0.1, 0.2, 0.4)
#: poured spheres and the floor's radius [mean diameters] per size
SIZES = {"full": {"n": 2000, "floor_radius": 26.0},
         "quick": {"n": 300, "floor_radius": 14.0}}
R_MEAN, R_SPREAD, RHO, G = 2.0e-3, 0.15, 2500.0, 9.81
KN, MU, RESTITUTION, ETA_ROLL = 5.0e3, 0.5, 0.5, 0.3
#: pouring rate [1/s] per poured sphere count: the pour lasts N / RATE
RATE = {"full": 2000.0, "quick": 1000.0}
KE_SETTLED = 1.0e-6
T_CHECK, T_MAX_AFTER = 0.02, 3.0
#: time between insertions [s] (each adds the spheres due; the neighbour lists are
#: rebuilt after it)
T_INSERT = 0.01
N_SECTORS = 8
FIT_RANGE = (0.2, 0.8)
PHI_BULK = 0.6  # packing fraction assumed to place the insertion box


def contact_law(mu_roll):
    import dem

    return dem.LinearSpring(kn=KN, kt=2.0 / 7.0 * KN, mu=MU, restitution=RESTITUTION,
                            rolling=dem.Rolling(mu_roll, eta_roll=ETA_ROLL))


def floor_bodies(floor_radius):
    """Bodies holding the rough floor: touching fixed spheres of radius ``R_MEAN`` on a
    square lattice within ``floor_radius`` mean diameters of the axis, over z = 0."""
    import dem

    d = 2.0 * R_MEAN
    g = np.arange(-math.floor(floor_radius), math.floor(floor_radius) + 1) * d
    x, y = np.meshgrid(g, g, indexing="ij")
    keep = x**2 + y**2 <= (floor_radius * d) ** 2
    xy = np.column_stack([x[keep], y[keep]])
    b = dem.Bodies.empty(3)
    b.add_spheres(np.column_stack([xy, np.full(len(xy), R_MEAN)]), R_MEAN, RHO)
    b.fix(np.arange(b.n))
    b.add_plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    return b


def on_floor(bodies, ids, floor_radius):
    """The bodies of ``ids`` whose centres lie within the floor's disk less one mean
    diameter (the others rolled off it onto the plane)."""
    d = 2.0 * R_MEAN
    r = np.hypot(bodies.pos[ids, 0], bodies.pos[ids, 1])
    return ids[r < (floor_radius - 1.0) * d]


def time_step(law):
    """The engine's default step for the lightest poured sphere on this law [s]."""
    import dem

    b = dem.Bodies.spheres([[0.0, 0.0, 0.0]], radius=R_MEAN * (1.0 - R_SPREAD), density=RHO)
    return dem.Simulation(b, law, gravity=[0.0, 0.0, -G]).dt


def insertion_box(n):
    """(lo, hi) [m] of the insertion box for ``n`` spheres."""
    d = 2.0 * R_MEAN
    bulk = n * math.pi / 6.0 * d**3 * (1.0 + 3.0 * R_SPREAD**2) / PHI_BULK
    apex = (3.0 * bulk / math.pi) ** (1.0 / 3.0)  # a 45 deg cone: h = R
    z0 = 2.0 * R_MEAN + apex + 2.0 * d
    return [-3.0 * d, -3.0 * d, z0], [3.0 * d, 3.0 * d, z0 + 4.0 * d]


def pour(mu_roll, n, floor_radius, rate, seed=1, trace=None):
    """Pour ``n`` spheres at ``rate`` [1/s] and let them settle.

    Returns the positions [m] and radii [m] of the poured spheres still over the floor
    and the run's information (counts, time step, simulated and wall time, whether it
    settled and the last kinetic-energy ratio). ``trace(line)``, when given, receives a
    line of progress every 0.02 s of simulated time.
    """
    import dem
    from dem.insertion import Inserter

    law = contact_law(mu_roll)
    dt = time_step(law)
    b = floor_bodies(floor_radius)
    n_floor = int(np.count_nonzero(b.kind == dem.Shape.SPHERE))
    lo, hi = insertion_box(n)
    ins = Inserter(lo, hi, n, rate, (R_MEAN * (1.0 - R_SPREAD), R_MEAN * (1.0 + R_SPREAD)),
                   RHO, every=max(1, round(T_INSERT / dt)), seed=seed)
    sim = dem.Simulation(b, law, dt=dt, gravity=[0.0, 0.0, -G], controllers=[ins])
    d = 2.0 * R_MEAN
    m_mean = RHO * math.pi / 6.0 * d**3
    t0 = time.perf_counter()
    chunk = max(1, round(T_CHECK / dt))
    t_pour = n / rate
    ratio, settled = math.inf, False
    while sim.time < t_pour + T_MAX_AFTER:
        sim.run(chunk, progress=False)
        if trace:
            trace(f"t {sim.time:.2f} s, {ins.inserted} poured, KE ratio {ratio:.2g}, "
                  f"{time.perf_counter() - t0:.0f} s")
        if ins.inserted < n or sim.time < t_pour:
            continue
        ids = on_floor(b, ins.ids, floor_radius)
        ke = 0.5 * float(np.sum(b.mass[ids] * np.sum(b.vel[ids] ** 2, axis=1)))
        ratio = ke / (max(ids.size, 1) * m_mean * G * d)
        if ratio < KE_SETTLED:
            settled = True
            break
    kept = on_floor(b, ins.ids, floor_radius)
    info = {"n": int(ins.inserted), "n_escaped": int(ins.inserted - kept.size),
            "n_floor": n_floor, "dt": sim.dt,
            "sim_time": sim.time, "seconds": time.perf_counter() - t0,
            "settled": settled, "ke_ratio": ratio}
    return b.pos[kept].copy(), b.radius[kept].copy(), info


def surface_points(pos, radius):
    """The free surface: per (sector, radial bin) cell the highest top (z + r).
    Returns (r [m], height above the floor's tops [m], bin index, sector) rows."""
    d = 2.0 * R_MEAN
    r = np.hypot(pos[:, 0], pos[:, 1])
    top = pos[:, 2] + radius - 2.0 * R_MEAN
    sector = np.floor((np.arctan2(pos[:, 1], pos[:, 0]) + math.pi)
                      / (2.0 * math.pi) * N_SECTORS).astype(int) % N_SECTORS
    rbin = np.floor(r / d).astype(int)
    rows = []
    for s in range(N_SECTORS):
        for k in np.unique(rbin[sector == s]):
            cell = np.flatnonzero((sector == s) & (rbin == k))
            i = cell[np.argmax(top[cell])]
            rows.append((r[i], top[i], k, s))
    return np.array(rows)


def angle_of_repose(pos, radius):
    """Angle [deg], its standard error [deg], pile radius R_p [m], the median profile
    (bin centres [m], heights [m]) and the fit (a [m], s [-], r range [m])."""
    d = 2.0 * R_MEAN
    pts = surface_points(pos, radius)
    n_bins = int(pts[:, 2].max()) + 1
    prof = np.full(n_bins, np.nan)
    for k in range(n_bins):
        h = pts[pts[:, 2] == k, 1]
        if h.size:
            prof[k] = np.median(h)
    edge = 0
    while edge < n_bins and prof[edge] > d:
        edge += 1
    r_pile = edge * d
    centre = (pts[:, 2] + 0.5) * d
    sel = (centre >= FIT_RANGE[0] * r_pile) & (centre <= FIT_RANGE[1] * r_pile)
    x, z = pts[sel, 0], pts[sel, 1]
    if x.size < 3 or np.ptp(x) == 0.0:
        raise RuntimeError(f"no pile to fit: R_p = {r_pile:.3g} m, {x.size} surface points")
    slope, a = np.polyfit(x, z, 1)
    res = z - (a + slope * x)
    se = math.sqrt(float(res @ res) / (x.size - 2) / float(np.sum((x - x.mean()) ** 2)))
    return {"angle_deg": math.degrees(math.atan(-slope)),
            "angle_err_deg": math.degrees(se / (1.0 + slope**2)),
            "pile_radius": r_pile, "pile_height": float(np.nanmax(prof)),
            "n_fit_points": int(x.size),
            "profile_r": ((np.arange(n_bins) + 0.5) * d).tolist(),
            "profile_h": [None if not np.isfinite(h) else float(h) for h in prof],
            "fit": {"a": float(a), "slope": float(slope),
                    "r_range": [FIT_RANGE[0] * r_pile, FIT_RANGE[1] * r_pile]}}


def run(size="full", mu_rolls=MU_ROLLS, seed=1, log=None):
    """Every case at ``size``; the results as the JSON holds them."""
    cfg = SIZES[size]
    cases = []
    for mu_roll in mu_rolls:
        pos, radius, info = pour(mu_roll, cfg["n"], cfg["floor_radius"], RATE[size], seed)
        case = {"mu_roll": float(mu_roll), **info, **angle_of_repose(pos, radius)}
        cases.append(case)
        if log:
            log(f"mu_roll {mu_roll:g}: {case['angle_deg']:.1f} +- "
                f"{case['angle_err_deg']:.1f} deg, R_p {case['pile_radius'] * 1e3:.0f} mm, "
                f"{case['n']} spheres, {case['sim_time']:.2f} s simulated "
                f"({'settled' if case['settled'] else 'NOT settled'}), "
                f"{case['seconds']:.0f} s")
    return {"size": size, "n": cfg["n"], "floor_radius_d": cfg["floor_radius"],
            "rate": RATE[size], "seed": seed, "radius_mean": R_MEAN, "radius_spread": R_SPREAD,
            "density": RHO, "kn": KN, "kt": 2.0 / 7.0 * KN, "mu": MU,
            "restitution": RESTITUTION, "eta_roll": ETA_ROLL, "ke_settled": KE_SETTLED,
            "cases": cases}


def visualize(data):
    """Angle against mu_roll (left) and the settled surface profiles (right)."""
    import matplotlib.pyplot as plt

    cases = data["cases"]
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10.0, 4.2))
    mr = [c["mu_roll"] for c in cases]
    ax.errorbar(mr, [c["angle_deg"] for c in cases], yerr=[c["angle_err_deg"] for c in cases],
                fmt="o-", capsize=4, color="k")
    ax.set_xlabel("rolling friction coefficient mu_roll [-]")
    ax.set_ylabel("angle of repose [deg]")
    ax.set_xlim(-0.03, max(mr) + 0.03)
    lo = min(c["angle_deg"] - c["angle_err_deg"] for c in cases)
    hi = max(c["angle_deg"] + c["angle_err_deg"] for c in cases)
    ax.set_ylim(max(0.0, lo - 4.0), hi + 4.0)
    ax.set_title(f"{data['n']} spheres, mu = {data['mu']}")
    colours = plt.cm.viridis(np.linspace(0.0, 0.85, len(cases)))
    d_mm = 2e3 * data["radius_mean"]
    for c, col in zip(cases, colours, strict=True):
        r = np.array(c["profile_r"]) / (1e-3 * d_mm)
        h = np.array([np.nan if v is None else v for v in c["profile_h"]]) / (1e-3 * d_mm)
        seen = np.isfinite(h)  # bins without a sphere have no surface
        bx.plot(r[seen], h[seen], "o", ms=3, color=col, label=f"mu_roll = {c['mu_roll']:g}")
        f = c["fit"]
        rr = np.array(f["r_range"])
        bx.plot(rr / (1e-3 * d_mm), (f["a"] + f["slope"] * rr) / (1e-3 * d_mm), "-",
                color=col, lw=1.5)
    bx.set_xlabel("distance from the axis r / d [-]")
    bx.set_ylabel("surface height above the floor / d [-]")
    bx.set_title("surface: sector median (dots), fit over 20-80 % of R_p")
    bx.set_ylim(bottom=0.0)
    fig.legend(*bx.get_legend_handles_labels(), loc="lower center", ncol=len(cases),
               fontsize=8, bbox_to_anchor=(0.5, 0.0))
    fig.tight_layout(rect=(0.0, 0.07, 1.0, 1.0))
    return fig


def markdown(data):
    """The docs' table."""
    lines = ["| mu_roll [-] | angle of repose [deg] | pile radius [mm] | pile height [mm] "
             "| spheres | simulated [s] | settled | wall [s] |",
             "|---|---|---|---|---|---|---|---|"]
    for c in data["cases"]:
        lines.append(f"| {c['mu_roll']:g} | {c['angle_deg']:.1f} ± {c['angle_err_deg']:.1f} "
                     f"| {c['pile_radius'] * 1e3:.0f} | {c['pile_height'] * 1e3:.0f} "
                     f"| {c['n']} | {c['sim_time']:.2f} | {'yes' if c['settled'] else 'no'} "
                     f"| {c['seconds']:.0f} |")
    return "\n".join(lines)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true",
                   help="300 spheres; write under benchmarks/work/ instead")
    p.add_argument("--figure", action="store_true",
                   help="redraw the figure from the saved JSON without running")
    p.add_argument("--markdown", action="store_true",
                   help="print the docs' table from the saved JSON")
    args = p.parse_args(argv)
    from dem.io.hdf5 import save_figure

    out, png = OUT, PNG
    if args.quick:
        out = C.WORK / "angle_of_repose.json"
        png = C.WORK / "angle_of_repose.png"
    if args.figure or args.markdown:
        if not out.is_file():
            print(f"error: {C.display_path(out)} not found: run the script first",
                  file=sys.stderr)
            sys.exit(2)
        data = json.loads(out.read_text())
        if args.markdown:
            print(markdown(data))
        if args.figure:
            save_figure(visualize(data), png, data=out.name)
            print(f"wrote {C.display_path(png)}")
        return
    t0 = time.perf_counter()
    data = run("quick" if args.quick else "full", log=print)
    data.update({"machine": C.machine_info(), "software": C.our_versions(), "date": C.now(),
                 "seconds": time.perf_counter() - t0})
    C.write_json(out, data)
    save_figure(visualize(data), png, data=out.name)
    print(markdown(data))
    print(f"wrote {C.display_path(out)} and {C.display_path(png)}")


if __name__ == "__main__":
    import os

    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    main()
