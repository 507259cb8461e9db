"""Contact detection: error against time per contact, ADMM and the exact solver vs surface nodes.

``python benchmarks/contact_speed_accuracy.py`` times, on one thread, the contact
summary of M (default 400) random overlapping poses of four pairs — box–box (3D),
polygon–polygon (2D), polyhedron–polyhedron (3D) and a custom superellipsoid pair (3D) —
by

- ADMM at tolerances 1e-2 ... 1e-10, cold (first contact) and warm (the same pairs one
  small rigid motion later, started from the previous solution, as in a running scene);
- the exact polytope solver (polytope pairs);
- the LS-DEM surface-node method with 10 ... 10^4 nodes on the home body.

Error: the relative error of the elastic normal force ``kn δ n`` against the reference
(the exact solver for polytopes; ADMM at 1e-9, the floor of its difference
gradients, for the superellipsoids, whose SDF is the distance from a Newton solve for
the nearest surface point), i.e.
``|δ n − δ_ref n_ref| / δ_ref``, and the contact point's error relative to the body size.
Poses: B placed along a random direction at the distance that gives an overlap of 1 %
of the size (bisection on the reference), both bodies randomly turned.

It also runs a flowing assembly (2D polygons poured into a box, ``detection="admm"``)
and records the ADMM iterations of every touching contact every 50 steps: their
distribution with warm starts is the paper's claim (1–2 iterations on average).

Writes ``benchmarks/results/contact_speed_accuracy.json`` and ``.png``:
``speedup_vs_nodes`` is, per pair, the node method's time per contact at 1e-6 relative
force error (interpolated in log-log between node counts; a lower bound when no node
count reaches it) over the time of the fastest of ADMM (warm) and the exact solver at
that error; ``admm_mean_iterations`` is the flowing assembly's mean.
"""

import math
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import _common as C

OUT = C.RESULTS / "contact_speed_accuracy.json"
TOLS = (1e-2, 1e-3, 1e-4, 1e-6, 1e-8, 1e-10)
# the superellipsoids' reference is ADMM itself, at the floor the differences allow
TOLS_CUSTOM = TOLS[:-1]
REF_TOL = 1e-9
NODES = (10, 30, 100, 300, 1000, 3000, 10000)
TARGET = 1e-6


def main():
    import numba
    import numpy as np

    import dem
    from dem.contact.detection.admm import custom_address, make_admm
    from dem.contact.detection.nodes import nodes_as3, nodes_contact_fn, surface_nodes
    from dem.contact.detection.polytope import polytope_contact

    superellipsoid = _superellipsoid_sdf()
    m_pairs = C.env_int("M", 400)
    reps = C.env_int("REPS", 5)
    rng = np.random.default_rng(11)

    admm = make_admm(superellipsoid)
    address = custom_address(superellipsoid)  # the node method evaluates it too

    @numba.njit
    def _store(out, k, a0, a1, a2, a3, a4, a5, a6, a7):
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = a0, a1, a2, a3
        out[k, 4], out[k, 5], out[k, 6], out[k, 7] = a4, a5, a6, a7

    def shapes():
        ang = np.sort(rng.uniform(0, 2 * np.pi, 7))
        poly2 = dem.ConvexPolygon(0.01 * np.stack([np.cos(ang), np.sin(ang)], 1))
        poly3 = dem.ConvexPolyhedron.from_vertices(rng.normal(size=(12, 3)) * 0.006)
        return {
            "box-box": (3, dem.Box([0.01, 0.007, 0.005])),
            "polygon-polygon": (2, poly2),
            "polyhedron-polyhedron": (3, poly3),
            "superellipsoid-superellipsoid": (3, dem.CustomShape(
                superellipsoid, 0.0105, 3, params=(0.01, 0.007, 0.005, 4.0))),
        }

    @numba.njit
    def run_exact(dim, pos, rot, geo, out):
        for k in range(out.shape[0]):
            r = polytope_contact(dim, 0, 2 * k, 0, 2 * k + 1, 0.0, 0.0, 0.0, pos, rot, geo)
            _store(out, k, r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7])

    @numba.njit
    def run_admm(dim, kind, pos, rot, normal, geo, warm, tol, out, iters, cap=500):
        for k in range(out.shape[0]):
            r = admm(dim, kind, 0, 2 * k, kind, 0, 2 * k + 1, 0.0, 0.0, 0.0, pos, rot,
                     normal, geo, warm, k, tol, cap)
            _store(out, k, r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8])
            iters[k] = r[8]

    @numba.njit
    def run_nodes(dim, kind, nodes, pos, rot, normal, geo, out):
        for k in range(out.shape[0]):
            r = nodes_contact_fn(address, dim, 2 * k, nodes, kind, 0, 2 * k + 1, 0.0, 0.0,
                                 0.0, pos, rot, normal, geo)
            _store(out, k, r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7])

    def scene(dim, shape, m):
        """2m bodies: pairs (2k, 2k+1) at random poses; B on a random direction."""
        b = dem.Bodies.empty(dim)
        if dim == 2:
            rot = rng.uniform(0, 2 * np.pi, 2 * m)
        else:
            q = rng.normal(size=(2 * m, 4))
            rot = q / np.linalg.norm(q, axis=1, keepdims=True)
        b.add_shapes(shape, np.zeros((2 * m, dim)), 1000.0, rot=rot)
        e = rng.normal(size=(m, dim))
        e /= np.linalg.norm(e, axis=1, keepdims=True)
        return b, e

    def timed(fn, *args):
        ts = []
        for _ in range(reps):
            t = time.perf_counter()
            fn(*args)
            ts.append(time.perf_counter() - t)
        return C.median(ts)

    results = {}
    for name, (dim, shape) in shapes().items():
        b, e = scene(dim, shape, m_pairs)
        geo = b.table.arrays()
        kind = int(b.kind[0])
        size = float(b.radius[0])
        exact = kind != dem.Shape.CUSTOM
        pos, rot, normal = b.pos, b.rot, b.normal
        out = np.zeros((m_pairs, 8))
        iters = np.zeros(m_pairs, np.int64)

        def reference(d):
            pos[1::2] = d[:, None] * e
            if exact:
                run_exact(dim, pos, rot, geo, out)
            else:
                run_admm(dim, kind, pos, rot, normal, geo, np.zeros((m_pairs, 16)),
                         REF_TOL, out, iters, 2000)
            return out[:, 0].copy()

        # bisection: distance with overlap 1 % of the size
        lo, hi = np.zeros(m_pairs), np.full(m_pairs, 2.5 * size)
        for _ in range(50):
            mid = 0.5 * (lo + hi)
            ov = reference(mid)
            inside = ov > 0.01 * size
            lo, hi = np.where(inside, mid, lo), np.where(inside, hi, mid)
        d = 0.5 * (lo + hi)
        reference(d)
        ref = out.copy()
        ok = ref[:, 0] > 0.0
        fref = ref[:, 0:1] * ref[:, 1:4]

        def errors(res):
            f = np.where(res[:, :1] > 0.0, res[:, 0:1] * res[:, 1:4], 0.0)
            fe = np.linalg.norm(f - fref, axis=1) / ref[:, 0]
            ce = np.linalg.norm(res[:, 4:7] - ref[:, 4:7], axis=1) / size
            return float(np.median(fe[ok])), float(np.max(fe[ok])), float(np.median(ce[ok]))

        entry = {"dim": dim, "size_m": size, "pairs": int(ok.sum()), "admm": [],
                 "nodes": []}
        if exact:
            t = timed(run_exact, dim, pos, rot, geo, out)
            fe_med, fe_max, ce = errors(out)
            entry["exact"] = {"s_per_contact": t / m_pairs, "force_error_median": fe_med,
                              "force_error_max": fe_max}
        for tol in TOLS if exact else TOLS_CUSTOM:
            warm = np.zeros((m_pairs, 16))
            run_admm(dim, kind, pos, rot, normal, geo, warm, tol, out, iters)  # compile
            t_cold = timed(lambda: run_admm(dim, kind, pos, rot, normal, geo,
                                            np.zeros((m_pairs, 16)), tol, out, iters))
            it_cold = float(iters.mean())
            # warm: move B by a small rigid step and solve from the stored iterates
            warm0 = np.zeros((m_pairs, 16))
            run_admm(dim, kind, pos, rot, normal, geo, warm0, tol, out, iters)
            step = 1e-4 * size * rng.normal(size=(m_pairs, dim))
            pos[1::2] += step
            ws, t_w = [], []
            for _ in range(reps):
                w = warm0.copy()
                t0 = time.perf_counter()
                run_admm(dim, kind, pos, rot, normal, geo, w, tol, out, iters)
                t_w.append(time.perf_counter() - t0)
                ws.append(float(iters.mean()))
            res_warm = out.copy()
            if exact:
                run_exact(dim, pos, rot, geo, out)
            else:
                run_admm(dim, kind, pos, rot, normal, geo, np.zeros((m_pairs, 16)),
                         REF_TOL, out, iters, 2000)
            ref_moved = out.copy()
            pos[1::2] -= step
            fm = ref_moved[:, 0:1] * ref_moved[:, 1:4]
            fw = np.where(res_warm[:, :1] > 0, res_warm[:, 0:1] * res_warm[:, 1:4], 0.0)
            okm = ref_moved[:, 0] > 0
            fe_warm = float(np.median(np.linalg.norm(fw - fm, axis=1)[okm]
                                      / ref_moved[okm, 0]))
            run_admm(dim, kind, pos, rot, normal, geo, np.zeros((m_pairs, 16)), tol, out,
                     iters)
            fe_med, fe_max, ce = errors(out)
            entry["admm"].append({
                "tol": tol, "cold_s_per_contact": t_cold / m_pairs,
                "warm_s_per_contact": C.median(t_w) / m_pairs,
                "cold_iterations_mean": it_cold, "warm_iterations_mean": C.median(ws),
                "force_error_median": fe_med, "force_error_max": fe_max,
                "warm_force_error_median": fe_warm, "point_error_median": ce})
        for nn in NODES:
            nodes = nodes_as3(surface_nodes(b.table.shapes[0], nn, dim))
            run_nodes(dim, kind, nodes, pos, rot, normal, geo, out)
            t = timed(run_nodes, dim, kind, nodes, pos, rot, normal, geo, out)
            fe_med, fe_max, ce = errors(out)
            entry["nodes"].append({"nodes": nn, "s_per_contact": t / m_pairs,
                                   "force_error_median": fe_med, "force_error_max": fe_max,
                                   "point_error_median": ce,
                                   "node_storage_bytes": int(nodes.nbytes)})
        entry["speedup_vs_nodes"] = _speedup(entry)
        results[name] = entry
        print(f"{name}: speed-up vs nodes at {TARGET:g} force error: "
              f"{entry['speedup_vs_nodes']}")
    flow = _flowing_assembly()
    out = {"target_force_error": TARGET, "pairs_per_case": m_pairs, "reps": reps,
           "cases": results, "flowing_assembly": flow,
           "admm_mean_iterations": flow["mean_iterations"],
           "speedup_vs_nodes": {k: v["speedup_vs_nodes"]["value"]
                                for k, v in results.items()},
           "date": C.now(), "machine": C.machine_info()}
    C.write_json(OUT, out)
    _plot(results, flow)
    print(f"flowing assembly: mean ADMM iterations {flow['mean_iterations']:.2f} over "
          f"{flow['samples']} contact solves")
    print(f"wrote {C.display_path(OUT)} and .png")


def _superellipsoid_sdf():
    """The signed distance to the superellipsoid ``|x/a|^e + |y/b|^e + |z/c|^e = 1``
    (``p = (a, b, c, e)``, e >= 2) as a user-defined SDF.

    ADMM needs a true distance outside the body, and the gauge ``(r - 1) min(a, b, c)``
    is not one. The nearest surface point solves ``X - w + mu grad G(X) = 0, G(X) = 0``
    (G the implicit function): Newton, from the radial projection of w, with the
    diagonal Hessian of G eliminated (four unknowns, one division each). Outside the
    projection onto a convex set is unique, so this is the distance; inside it is the
    distance to the nearest surface point near the radial one, and where Newton would
    pass a centre of curvature (deep inside) the gauge value, a lower bound, instead.
    About 1 us per evaluation through the solvers' C call (the node method's time per
    node).
    """
    import numba

    @numba.njit
    def superellipsoid(x, y, z, p):
        a, b, c, e = p[0], p[1], p[2], p[3]
        m = min(a, min(b, c))
        g = abs(x / a) ** e + abs(y / b) ** e + abs(z / c) ** e
        if g == 0.0:
            return -m
        r = g ** (1.0 / e)
        X0, X1, X2 = x / r, y / r, z / r
        mu, last = 0.0, False
        for k in range(50):
            G0 = e * math.copysign(abs(X0 / a) ** (e - 1.0), X0) / a
            G1 = e * math.copysign(abs(X1 / b) ** (e - 1.0), X1) / b
            G2 = e * math.copysign(abs(X2 / c) ** (e - 1.0), X2) / c
            if k == 0:  # the multiplier that best fits X - w + mu grad G = 0
                mu = -((X0 - x) * G0 + (X1 - y) * G1 + (X2 - z) * G2) / (
                    G0 * G0 + G1 * G1 + G2 * G2)
            D0 = 1.0 + mu * e * (e - 1.0) * abs(X0 / a) ** (e - 2.0) / (a * a)
            D1 = 1.0 + mu * e * (e - 1.0) * abs(X1 / b) ** (e - 2.0) / (b * b)
            D2 = 1.0 + mu * e * (e - 1.0) * abs(X2 / c) ** (e - 2.0) / (c * c)
            if min(D0, min(D1, D2)) <= 0.0:
                return (r - 1.0) * m
            G = abs(X0 / a) ** e + abs(X1 / b) ** e + abs(X2 / c) ** e - 1.0
            r0, r1, r2 = X0 - x + mu * G0, X1 - y + mu * G1, X2 - z + mu * G2
            dmu = (G - (G0 * r0 / D0 + G1 * r1 / D1 + G2 * r2 / D2)) / (
                G0 * G0 / D0 + G1 * G1 / D1 + G2 * G2 / D2)
            d0, d1, d2 = -(r0 + G0 * dmu) / D0, -(r1 + G1 * dmu) / D1, -(r2 + G2 * dmu) / D2
            X0, X1, X2, mu = X0 + d0, X1 + d1, X2 + d2, mu + dmu
            if last:  # one step past 1e-10: round-off (quadratic convergence)
                break
            last = d0 * d0 + d1 * d1 + d2 * d2 <= 1e-20 * (m * m)
        else:
            return (r - 1.0) * m
        d = math.sqrt((X0 - x) ** 2 + (X1 - y) ** 2 + (X2 - z) ** 2)
        return d if g > 1.0 else -d

    return superellipsoid


def _loglog_time_at(points, target):
    """Time at ``target`` error by log-log interpolation over (error, time) points."""
    import numpy as np

    pts = sorted((e, t) for e, t in points if e > 0)
    reach = [(e, t) for e, t in pts if e <= target]
    if not reach:
        return None, False
    best = min(t for e, t in reach)
    above = [(e, t) for e, t in pts if e > target]
    if above:  # interpolate between the last point above and the first below
        e1, t1 = min(above, key=lambda p: p[0])
        e0, t0 = max(reach, key=lambda p: p[0])
        w = (np.log(target) - np.log(e1)) / (np.log(e0) - np.log(e1))
        best = min(best, float(np.exp(np.log(t1) + w * (np.log(t0) - np.log(t1)))))
    return best, True


def _speedup(entry):
    cands = [(a["warm_force_error_median"], a["warm_s_per_contact"]) for a in entry["admm"]]
    t_ours, ok = _loglog_time_at(cands, TARGET)
    method = "admm (warm)"
    if "exact" in entry and entry["exact"]["force_error_median"] <= TARGET:
        if t_ours is None or entry["exact"]["s_per_contact"] < t_ours:
            t_ours, method = entry["exact"]["s_per_contact"], "exact solver"
    nodes = [(n["force_error_median"], n["s_per_contact"]) for n in entry["nodes"]]
    t_nodes, reached = _loglog_time_at(nodes, TARGET)
    if not reached:
        t_nodes = max(n["s_per_contact"] for n in entry["nodes"])
    if t_ours is None:
        return {"value": None, "method": None, "nodes_reach_target": reached}
    return {"value": t_nodes / t_ours, "method": method, "nodes_reach_target": reached,
            "lower_bound": not reached, "ours_s": t_ours, "nodes_s": t_nodes}


def _flowing_assembly():
    """2D polygons poured into a box with ADMM detection; iterations per touching contact."""
    import numpy as np

    import dem

    rng = np.random.default_rng(3)
    b = dem.Bodies.empty(2)
    n = C.env_int("FLOW_N", 150)
    per_row = 10
    for k in range(n):
        m = int(rng.integers(4, 8))
        ang = np.sort(rng.uniform(0, 2 * np.pi, m))
        ang += np.linspace(0, 2 * np.pi, m, endpoint=False) - ang.mean() + np.pi
        r = 0.01 * rng.uniform(0.8, 1.0, m)
        shape = dem.ConvexPolygon(np.stack([r * np.cos(ang), r * np.sin(ang)], 1))
        b.add_shapes(shape, [[0.022 * (k % per_row + 0.5), 0.022 * (k // per_row + 0.5)]],
                     2500.0, rot=[rng.uniform(0, 2 * np.pi)],
                     vel=[rng.normal(0, 0.2, 2)])
    b.add_plane([0, 0], [0, 1])
    b.add_plane([0, 0], [1, 0])
    b.add_plane([0.22, 0], [-1, 0])
    sim = dem.Simulation(b, dem.LinearSpring(kn=1e5, kt=5e4, mu=0.4, restitution=0.3),
                         gravity=[0, -9.81], detection="admm", admm_tol=1e-8,
                         admm_max_iter=1000, threads=1)
    hist = np.zeros(64, np.int64)  # the last bin holds 63 and more
    total, longest = 0, 0
    failure = None
    for _ in range(C.env_int("FLOW_RECORDS", 200)):
        try:
            sim.run(50)
        except dem.SimulationError as err:  # reported, not hidden
            failure = str(err)
            break
        ss, sw = sim.shape_state, sim.shape_wall_state
        for it, geom in ((ss.iters, ss.pgeom), (sw.witers, sw.wgeom)):
            touching = geom[:, 0] > 0.0
            hist += np.bincount(np.minimum(it[touching], 63), minlength=64)
            total += int(it[touching].sum())
            longest = max(longest, int(it[touching].max(initial=0)))
    samples = int(hist.sum())
    return {"bodies": n, "steps": sim.step, "samples": samples,
            "mean_iterations": total / max(samples, 1), "max_iterations": longest,
            "histogram": hist.tolist(), "tol": 1e-8, "max_iter": 1000, "failure": failure,
            "share_at_most_2": float(hist[:3].sum() / max(samples, 1)),
            "share_over_20": float(hist[21:].sum() / max(samples, 1))}


def _plot(results, flow):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    fig, axes = plt.subplots(1, len(results) + 1, figsize=(4.2 * (len(results) + 1), 3.8))
    for ax, (name, e) in zip(axes, results.items(), strict=False):
        a = e["admm"]
        ax.loglog([x["warm_s_per_contact"] * 1e6 for x in a],
                  [max(x["warm_force_error_median"], 1e-16) for x in a], "o-",
                  label="ADMM, warm")
        ax.loglog([x["cold_s_per_contact"] * 1e6 for x in a],
                  [max(x["force_error_median"], 1e-16) for x in a], "s--", label="ADMM, cold")
        nd = e["nodes"]
        ax.loglog([x["s_per_contact"] * 1e6 for x in nd],
                  [max(x["force_error_median"], 1e-16) for x in nd], "^-",
                  label="surface nodes")
        if "exact" in e:
            ax.loglog([e["exact"]["s_per_contact"] * 1e6],
                      [max(e["exact"]["force_error_median"], 1e-16)], "k*", ms=12,
                      label="exact solver")
        ax.axhline(TARGET, color="0.6", lw=0.8)
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("time per contact [µs]")
        ax.set_ylabel("relative force error (median)")
    axes[0].legend(fontsize=7)
    ax = axes[-1]
    h = np.array(flow["histogram"])
    ax.bar(np.arange(h.size)[:20], h[:20] / max(h.sum(), 1))
    ax.set_xlabel("ADMM iterations per contact and step")
    ax.set_ylabel("share")
    ax.set_title(f"flowing polygons, warm: mean {flow['mean_iterations']:.2f}", fontsize=9)
    fig.tight_layout()
    fig.savefig(OUT.with_suffix(".png"), dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
