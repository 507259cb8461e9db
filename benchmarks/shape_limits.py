"""Where level-set shapes still fall short: the numbers docs/shapes.md and docs/rve.md
quote as limits.

a. **Equal 2D boxes stacked in line.** Two 0.2 m squares, the upper 1 mm into the
   lower, its sides offset by 0 to 10 mm: the contact normal (it should be vertical,
   and is since the corners take the faces their arcs cross).
b. **Polygon RVE consolidation.** The 40 pentagons and hexagons of
   ``tests/dem/test_rve.py`` consolidated to 100 kPa at the working friction 0.5 and
   frictionless (cap 100,000 steps): steps, wall time, unbalanced-force ratio,
   coordination, void ratio.
c. **Cube RVE consolidation.** 100 cubes (``kn = 1e5 N/m``, friction 0.5), cap 60,000
   steps; and 60 cubes from seeds 1 to 3, the same cap.

::

    python benchmarks/shape_limits.py   # writes benchmarks/results/shape_limits.json
"""

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C

OUT = C.RESULTS / "shape_limits.json"


def stacked_boxes():
    import numpy as np

    import dem

    rows = []
    for dx in (0.0, 1e-9, 1e-6, 5e-4, 1e-3, 2e-3, 1e-2):
        b = dem.Bodies.empty(2)
        b.add_shapes(dem.Box([0.1, 0.1]), np.array([[0.5, 0.4], [0.5 + dx, 0.599]]),
                     density=1000.0)
        sim = dem.Simulation(b, dem.LinearSpring(kn=1e4, kt=2e3, mu=0.5), dt=1e-5)
        c = sim.contacts()
        rows.append({"offset": dx, "normal": c["normal"][0].tolist(),
                     "overlap": float(c["overlap"][0])})
        print(f"offset {dx:g} m: normal {np.round(c['normal'][0], 6).tolist()}",
              flush=True)
    return rows


def consolidation(dim, n, shape, law, friction, cap, seed):
    from dem import rve

    t0 = time.perf_counter()
    row = {"dim": dim, "n": n, "seed": seed, "friction": friction, "cap": cap}
    try:
        p = rve.generate(dim, n, (0.8e-3, 1.2e-3), law, p0=1e5, seed=seed, damping=0.5,
                         friction=friction, max_relax_steps=cap, shape=shape)
        row["error"] = None
    except rve.RelaxationError as err:
        p, row["error"] = None, str(err).split(";")[0]
    row["wall_time"] = time.perf_counter() - t0
    if p is not None:
        r = p.response()
        row.update(steps=p.sim.step, unbalanced=r["unbalanced"],
                   coordination=r["coordination"], void_ratio=r["void_ratio"])
    print(row, flush=True)
    return row


def main():
    import numpy as np

    import dem
    from dem.shapes import ConvexPolygon

    def polygon(r, rng):
        return ConvexPolygon.regular(5 + int(rng.integers(2)), r)

    def cube(r, rng):
        return dem.Box([r / np.sqrt(3.0)] * 3)

    law2 = dem.LinearSpring(kn=1e8, kt=5e7, mu=0.5)
    law3 = dem.LinearSpring(kn=1e5, kt=5e4, mu=0.5)
    C.write_json(OUT, {
        "benchmark": "shape_limits", "date": C.now(), "machine": C.machine_info(),
        "versions": C.our_versions(), "revision": C.git_revision(),
        "stacked_boxes": stacked_boxes(),
        "polygon_rve": [consolidation(2, 40, polygon, law2, f, 100000, 6)
                        for f in (None, 0.0)],
        "cube_rve": [consolidation(3, 100, cube, law3, None, 60000, 3)],
        "cube_rve_60": [consolidation(3, 60, cube, law3, None, 60000, seed)
                        for seed in (1, 2, 3)]})


if __name__ == "__main__":
    main()
