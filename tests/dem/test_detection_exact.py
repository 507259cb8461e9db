"""Exact contact detection of polytopes and the closed forms, against naive references.

The polytope-polytope kernel is checked against the same linear programme solved by
``scipy.optimize.linprog`` (its active set polished by a dense solve) where the deeper
optimum is a vertex, and against a separating-axis test over every face and every edge
pair where it is not (3D edge across edge), on seeded random convex polygons and
polyhedra, and on hand-worked box configurations; the contact point against the
depth-weighted mean of the deeper side's vertices inside the other body (3D), and in 2D
the corners' terms against a numpy walk over the arcs of each boundary inside the
other (:func:`arcs_ref`). Properties: the
overlap follows the penetration depth continuously as an edge slides off another, the
point slides as a resting box tilts, and for one vertex on a face or one edge on an
edge the force ``kn ov n`` at the point is minus the gradient of ``kn ov^2 / 2``
(conservative). The sphere kernels are checked against a closest point found face by
face in numpy; the wall kernels against the deepest-vertex formula. Shape rows are built
here by hand (in the body frame, faces ``n . x <= o``), so the tests depend only on the
table layout.
"""

import numpy as np
import pytest
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, HalfspaceIntersection
from scipy.spatial.transform import Rotation

from dem.contact.detection.analytic import (
    box_plane,
    sphere_box,
    sphere_plane,
    sphere_polytope,
    sphere_sphere,
)
from dem.contact.detection.polytope import (
    BLEND,
    DEEPER,
    PATCH_FROM,
    PATCH_TO,
    polytope_contact,
    polytope_plane,
)
from dem.shapes.kinds import BOX, POLYGON, POLYHEDRON
from dem.shapes.table import ShapeTable

SQ3 = np.sqrt(3.0)


# --------------------------------------------------------------------------- shapes
def polygon_rows(v):
    v = np.asarray(v, float)
    e = np.roll(v, -1, axis=0) - v
    n = np.column_stack([e[:, 1], -e[:, 0]]) / np.linalg.norm(e, axis=1)[:, None]
    faces = np.column_stack([n, np.zeros(len(v)), np.einsum("ij,ij->i", n, v)])
    return {"kind": POLYGON, "param": np.zeros(4),
            "verts": np.column_stack([v, np.zeros(len(v))]), "faces": faces,
            "tris": np.zeros((0, 3), np.int64),
            "bounding_radius": np.linalg.norm(v, axis=1).max()}


def polyhedron_rows(p):
    hull = ConvexHull(p)
    v = p[hull.vertices]
    index = {j: i for i, j in enumerate(hull.vertices)}
    tris = np.array([[index[j] for j in s] for s in hull.simplices])
    # each triangle counter-clockwise seen from outside
    for t, eq in zip(tris, hull.equations, strict=True):
        if np.cross(v[t[1]] - v[t[0]], v[t[2]] - v[t[0]]) @ eq[:3] < 0:
            t[[1, 2]] = t[[2, 1]]
    keep = np.unique(np.round(hull.equations, 9), axis=0, return_index=True)[1]
    eqs = hull.equations[keep]  # one row per face (coplanar triangles share one)
    return {"kind": POLYHEDRON, "param": np.zeros(4), "verts": v,
            "faces": np.column_stack([eqs[:, :3], -eqs[:, 3]]), "tris": tris,
            "bounding_radius": np.linalg.norm(v, axis=1).max()}


def box_rows(h):
    h = np.asarray(h, float)
    param = np.zeros(4)
    param[:len(h)] = h
    if len(h) == 2:
        rows = polygon_rows(np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]]) * h)
    else:
        corners = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
        rows = polyhedron_rows(corners * h)  # a hull: two triangles per face
        rows["faces"] = np.array([[*s * np.eye(3)[i], h[i]] for i in range(3)
                                  for s in (-1, 1)])
    rows.update(kind=BOX, param=param)
    return rows


def random_polygon(rng):
    a = np.sort(rng.uniform(0.0, 2.0 * np.pi, rng.integers(5, 9)))
    p = rng.uniform(0.6, 1.4, (len(a), 1)) * np.column_stack([np.cos(a), np.sin(a)])
    p = p * rng.uniform(0.5, 1.5, 2)  # elongated
    return polygon_rows(p[ConvexHull(p).vertices] - p.mean(axis=0))


def random_polyhedron(rng):
    p = rng.normal(size=(rng.integers(8, 20), 3))
    p *= rng.uniform(0.6, 1.4, (len(p), 1)) / np.linalg.norm(p, axis=1)[:, None]
    return polyhedron_rows(p * rng.uniform(0.5, 1.5, 3))


def table(rows, scales=None):
    t = ShapeTable()
    for r in rows:
        t.add(r)
    if scales is not None:
        t.scale[:] = scales
    return t.arrays()


def random_table(dim, rng, n=5):
    make = random_polygon if dim == 2 else random_polyhedron
    h = [0.4, 0.7] if dim == 2 else [0.4, 0.7, 0.55]
    return table([make(rng) for _ in range(n - 1)] + [box_rows(h)],
                 rng.uniform(0.5, 1.5, n))


def rotation(dim, rot, b):
    if dim == 2:
        c, s = np.cos(rot[b, 0]), np.sin(rot[b, 0])
        return np.array([[c, -s], [s, c]])
    return Rotation.from_quat(np.roll(rot[b], -1)).as_matrix()


def random_rot(dim, rng, n):
    if dim == 2:
        return rng.uniform(-np.pi, np.pi, (n, 1))
    return np.ascontiguousarray(np.roll(Rotation.random(n, random_state=rng).as_quat(), 1,
                                        axis=1))


def world(geo, s, dim, pos, rot, b, shift=0.0):
    """World vertices (k, dim) and faces (m, dim + 1) ``n . x <= o`` of body ``b``."""
    sc, vstart, verts, fstart, faces = geo[1][s], geo[2], geo[3], geo[4], geo[5]
    r = rotation(dim, rot, b)
    p = pos[b] + shift
    v = sc * verts[vstart[s]:vstart[s + 1], :dim] @ r.T + p
    n = faces[fstart[s]:fstart[s + 1], :dim] @ r.T
    return v, np.column_stack([n, sc * faces[fstart[s]:fstart[s + 1], 3] + n @ p])


# --------------------------------------------------------------------------- references
def deepest_ref(fo, fi):
    """min over the inner body of max_f (n_f . x - o_f): (t, x, normal) by linprog."""
    d = fo.shape[1] - 1
    a = np.vstack([np.column_stack([fo[:, :d], -np.ones(len(fo))]),
                   np.column_stack([fi[:, :d], np.zeros(len(fi))])])
    b = np.concatenate([fo[:, d], fi[:, d]])
    res = linprog(np.eye(d + 1)[d], A_ub=a, b_ub=b, bounds=[(None, None)] * (d + 1),
                  method="highs")
    active = b - a @ res.x < 1e-7
    z = np.linalg.lstsq(a[active], b[active], rcond=None)[0]  # polish the vertex
    tied = fo[:, :d] @ z[:d] - fo[:, d] > z[d] - 1e-9
    n = fo[tied, :d].sum(axis=0)
    return z[d], z[:d], n / max(np.linalg.norm(n), 1e-300)


def edges_ref(verts, faces):
    """Edges (i, j) of a polytope: vertex pairs on two common face planes."""
    d = verts.shape[1]
    on = np.abs(verts @ faces[:, :d].T - faces[:, d]) < 1e-9 * np.abs(verts).max()
    return np.array([(i, j) for i in range(len(verts)) for j in range(i + 1, len(verts))
                     if np.count_nonzero(on[i] & on[j]) >= 2])


def separating_axes_ref(va, fa, vb, fb):
    """Least overlap ``max_A u . x - min_B u . y`` over every face normal and every edge
    pair (3D): ``(ov, "A" | "B" | "edge", u, point)`` with the deepest vertex (faces) or
    the midpoint of the edges' closest points."""
    best = (np.inf,)
    for g, u in enumerate(fa[:, :3]):
        ov = fa[g, 3] - (vb @ u).min()
        if ov < best[0]:
            best = (ov, "A", u, vb[np.argmin(vb @ u)])
    for f, u in enumerate(fb[:, :3]):
        ov = fb[f, 3] - (va @ u).min()
        if ov < best[0]:
            best = (ov, "B", u, va[np.argmin(va @ u)])
    ea, eb = edges_ref(va, fa), edges_ref(vb, fb)
    da, db = va[ea[:, 1]] - va[ea[:, 0]], vb[eb[:, 1]] - vb[eb[:, 0]]
    u = np.cross(da[:, None, :], db[None, :, :])  # (edges of A, edges of B, 3)
    size = np.linalg.norm(da, axis=1)[:, None] * np.linalg.norm(db, axis=1)[None, :]
    keep = np.linalg.norm(u, axis=2) > 1e-6 * size
    u = u[keep] / np.linalg.norm(u[keep], axis=1)[:, None]
    ia, ib = np.nonzero(keep)
    u = np.concatenate([u, -u])
    ia, ib = np.concatenate([ia, ia]), np.concatenate([ib, ib])
    pa, pb = va @ u.T, vb @ u.T  # (vertices, axes)
    hi, lo = pa.max(axis=0), pb.min(axis=0)
    eps = 1e-9 * np.abs(va).max()
    # the edges must be the extreme features along the axis (parallel edges tie)
    on = ((pa[ea[ia, 0], np.arange(len(u))] > hi - eps)
          & (pa[ea[ia, 1], np.arange(len(u))] > hi - eps)
          & (pb[eb[ib, 0], np.arange(len(u))] < lo + eps)
          & (pb[eb[ib, 1], np.arange(len(u))] < lo + eps))
    ov = np.where(on, hi - lo, np.inf)
    k = np.argmin(ov)
    if ov[k] < best[0]:
        a0, b0, e, f = va[ea[ia[k], 0]], vb[eb[ib[k], 0]], da[ia[k]], db[ib[k]]
        s, t = np.linalg.solve([[e @ e, -e @ f], [e @ f, -f @ f]], [(b0 - a0) @ e,
                                                                     (b0 - a0) @ f])
        best = (ov[k], "edge", u[k], 0.5 * (a0 + s * e + b0 + t * f))
    return best


def depth_ref(vi, fo):
    """Depth of the vertices ``vi`` inside the body with faces ``fo`` (0 outside)."""
    d = vi.shape[1]
    return np.maximum(-np.max(vi @ fo[:, :d].T - fo[:, d], axis=1), 0.0)


def rules_ref(geo, sa, sb, dim, pos, rot):
    """The contact from the two linear programmes and, where the deeper optimum is no
    vertex (3D), the separating axes: ``(ov, n, c, rule)`` of bodies 0 and 1, ``rule``
    one of "apart", "2D" (2D, no vertex), ["sat-"]"vertex" or "vertices" (how many
    weigh in the point), "sat-edge"."""
    va, fa = world(geo, sa, dim, pos, rot, 0)
    vb, fb = world(geo, sb, dim, pos, rot, 1)
    t1, x1, m1 = deepest_ref(fb, fa)
    if t1 >= 0.0:
        return -t1, None, None, "apart"
    t2, x2, m2 = deepest_ref(fa, fb)
    d1, d2 = -t1, -t2
    tie = 1e-9 * max(np.abs(va).max(), np.abs(vb).max())
    n1 = np.count_nonzero(np.max(va @ fb[:, :dim].T - fb[:, dim], axis=1) <= t1 + tie)
    n2 = np.count_nonzero(np.max(vb @ fa[:, :dim].T - fa[:, dim], axis=1) <= t2 + tie)
    use1 = d1 > d2 + tie or (d1 >= d2 - tie and n1 >= n2)
    rule = ""
    corners = corners_ref(va, fa, vb, fb) if dim == 2 else None
    if corners is not None:
        oc, nc, cc, rule, vmax = corners
        ov, n, c = (d1, -m1, x1 + 0.5 * d1 * m1) if use1 else (d2, m2, x2 + 0.5 * d2 * m2)
        u = np.clip((ov / vmax - 1) / (DEEPER - 1), 0, 1)  # deeper than any corner
        if u == 0:
            return oc, nc, cc, rule
        m = (1 - u) * nc + u * n
        if np.linalg.norm(m) > 1e-9:  # else opposite normals cancel: the programme's
            n = m / np.linalg.norm(m)
        return (1 - u) * oc + u * ov, n, (1 - u) * cc + u * c, "deeper"
    if (n1 if use1 else n2) == 0:
        if dim == 2:  # not a vertex in 2D: only for deep overlaps, kept as it is
            return (d1, -m1, x1 + 0.5 * d1 * m1, "2D") if use1 else (
                d2, m2, x2 + 0.5 * d2 * m2, "2D")
        ov, axis, u, p = separating_axes_ref(va, fa, vb, fb)
        if axis == "edge":
            return ov, u, p, "sat-edge"
        use1, rule = axis == "B", "sat-"
        if use1:
            d1, x1, m1 = ov, p, u
        else:
            d2, x2, m2 = ov, p, u
    # the point: the mean of the searched body's vertices inside the other weighted by
    # their depth, moved along the normal to the deepest point's level
    w, vi = (depth_ref(va, fb), va) if use1 else (depth_ref(vb, fa), vb)
    ov, m, z = (d1, m1, x1) if use1 else (d2, m2, x2)  # m: the outer body's normal
    mean = w @ vi / w.sum() if w.sum() > 0.0 else z
    c = mean - ((mean - z) @ m) * m + 0.5 * ov * m
    n = -m1 if use1 else m2
    return ov, n, c, rule + ("vertex" if np.count_nonzero(w) == 1 else "vertices")


def intersection_ref(fa, fb):
    """Volume and centroid of the intersection of two convex polyhedra (world faces), by
    qhull from a Chebyshev centre."""
    a = np.vstack([fa, fb])
    norm = np.linalg.norm(a[:, :3], axis=1)
    res = linprog(-np.eye(4)[3], A_ub=np.column_stack([a[:, :3], norm]), b_ub=a[:, 3],
                  bounds=[(None, None)] * 3 + [(0, None)], method="highs")
    inner = res.x[:3]
    pts = HalfspaceIntersection(np.column_stack([a[:, :3], -a[:, 3]]), inner).intersections
    hull = ConvexHull(pts)
    vol = np.array([abs(np.linalg.det(pts[t] - inner)) / 6 for t in hull.simplices])
    cen = np.array([(pts[t].sum(axis=0) + inner) / 4 for t in hull.simplices])
    return vol.sum(), vol @ cen / vol.sum()


def patch_ref(geo, sa, sb, pos, rot):
    """3D: the contact of :func:`rules_ref`, its point moved along the contact plane to
    the centroid of the intersection by the weight of :data:`PATCH_FROM` ..
    :data:`PATCH_TO` (rule "patch-..." where it moves)."""
    ov, n, c, rule = rules_ref(geo, sa, sb, 3, pos, rot)
    if rule == "apart":
        return ov, n, c, rule
    vol, cen = intersection_ref(world(geo, sa, 3, pos, rot, 0)[1],
                                world(geo, sb, 3, pos, rot, 1)[1])
    u = np.clip((np.sqrt(vol / ov**3) - PATCH_FROM) / (PATCH_TO - PATCH_FROM), 0.0, 1.0)
    if u == 0.0:
        return ov, n, c, rule
    e = cen - c
    return ov, n, c + u * u * (3 - 2 * u) * (e - (e @ n) * n), "patch-" + rule


def contact_ref(geo, sa, sb, dim, pos, rot):
    """The reference contact of bodies 0 and 1: :func:`rules_ref`, in 3D with the
    patches' points (:func:`patch_ref`)."""
    if dim == 2:
        return rules_ref(geo, sa, sb, dim, pos, rot)
    return patch_ref(geo, sa, sb, pos, rot)


def smooth_max_ref(d1, d2):
    """The smooth maximum of two depths and its gradient."""
    m, x = (d1 + d2) / 2, d1 - d2
    h = BLEND * m
    if abs(x) >= h:
        return (d1, 1.0, 0.0) if x > 0 else (d2, 0.0, 1.0)
    q = BLEND * x**2 / (8 * h**2)
    return (m + h / 4 + x**2 / (4 * h), 0.5 + BLEND / 8 + x / (2 * h) - q,
            0.5 + BLEND / 8 - x / (2 * h) - q)


def crossing_ref(p, q, f, entering):
    """Where the segment ``p -> q`` crosses the boundary of the polygon with faces ``f``
    (entering: the last face line it passes into; leaving: the first it passes out of),
    and that face."""
    den = f[:, :2] @ (q - p)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (f[:, 2] - f[:, :2] @ p) / den
    rows = np.nonzero(den < 0 if entering else den > 0)[0]
    k = rows[np.argmax(t[rows]) if entering else np.argmin(t[rows])]
    return p + np.clip(t[k], 0.0, 1.0) * (q - p), k


def support_ref(vo, fo, e, fe, x, fx):
    """The outer polygon's boundary from ``x`` (face ``fx``) counter-clockwise to ``e``
    (face ``fe``): its normal (the faces' normals weighted by their lengths to the
    fourth), its faces and each one's divisor, its length squared relative to the
    longest (1 for one face)."""
    tangent = np.array([-fo[fe, 1], fo[fe, 0]])
    if fe == fx and (e - x) @ tangent >= 0.0:
        return fo[fe, :2], fo[[fe]], np.ones(1)
    ks = [fx]
    while ks[-1] != fe:
        ks.append((ks[-1] + 1) % len(fo))
    points = np.array([x, *vo[[(k + 1) % len(fo) for k in ks[:-1]]], e])
    l4 = np.linalg.norm(np.diff(points, axis=0), axis=1) ** 4
    g = l4 @ fo[ks, :2]
    keep = l4 > 0.0
    return g / np.linalg.norm(g), fo[ks][keep], np.sqrt(l4[keep] / l4.max())


def smooth_min_ref(d1, d2):
    """The smooth minimum of two depths and its gradient, from the smooth maximum."""
    if abs(d1 - d2) >= BLEND * (d1 + d2) / 2:
        return (d1, 1.0, 0.0) if d1 < d2 else (d2, 0.0, 1.0)
    s, w1, w2 = smooth_max_ref(d1, d2)
    return d1 + d2 - s, 1 - w1, 1 - w2


def arcs_ref(vi, vo, fo):
    """The inner polygon's corners inside the outer one, each with the arc of the inner
    boundary it lies on (from where that boundary enters the outer to where it leaves):
    ``(w, G, corner)`` per corner, its depth and push: the smooth minimum of its two
    least distances to the faces of the arc's outer boundary (over their pieces'
    relative lengths squared) and those faces' normals weighted by its gradient, unless
    a face ahead is nearer (over how nearly head-on). None when no inner vertex is
    outside."""
    inside = np.max(vi @ fo[:, :2].T - fo[:, 2], axis=1) <= 0.0
    if inside.all():
        return None
    n = len(vi)
    start = np.nonzero(~inside)[0][0]
    order = [(start + i) % n for i in range(n + 1)]
    terms, i = [], 0
    while i < n:
        if inside[order[i + 1]]:
            e, fe = crossing_ref(vi[order[i]], vi[order[i + 1]], fo, True)
            j = i + 1
            while inside[order[j]]:
                j += 1
            x, fx = crossing_ref(vi[order[j - 1]], vi[order[j]], fo, False)
            g, fs, lam = support_ref(vo, fo, e, fe, x, fx)
            head = -1.0 - 2.0 * fo[:, :2] @ g  # the faces ahead, 1 head-on
            ahead = fo[head > 0]
            for k in order[i + 1:j]:
                dist = (fs[:, 2] - fs[:, :2] @ vi[k]) / lam
                two = np.argsort(dist, kind="stable")[:2]
                if len(two) == 1:
                    d, grad = dist[two[0]], fs[two[0], :2]
                else:
                    d, s1, s2 = smooth_min_ref(*dist[two])
                    grad = s1 * fs[two[0], :2] + s2 * fs[two[1], :2]
                cap = (ahead[:, 2] - ahead[:, :2] @ vi[k]) / head[head > 0]
                if len(cap) and cap.min() < d:
                    d, grad = cap.min(), ahead[np.argmin(cap), :2]
                terms.append((max(0.0, d), grad, vi[k]))
            i = j
        else:
            i += 1
    return terms


def corners_ref(va, fa, vb, fb):
    """2D, corners inside: each body's corners inside the other give a depth (the
    deepest's), a gradient and a point (the depth-weighted means of the corners'
    gradients and of the corners moved out along them by their depths, then in by half
    the deepest's); one term gives the overlap depth times the gradient's length along
    it; with both, the gradient of the smooth maximum's energy, summed into one force
    on its line of action. None when no corner weighs in."""
    terms, inside = [], 0
    for v, f, vo, sign in ((va, fb, vb, -1.0), (vb, fa, va, 1.0)):
        arcs = arcs_ref(v, vo, f)
        if arcs is None:  # wholly inside: the faces nearest
            w = depth_ref(v, f)
            g = f[np.argmax(v @ f[:, :2].T - f[:, 2], axis=1), :2]
        elif arcs:
            w, g, v = (np.array(x) for x in zip(*arcs, strict=True))
        else:
            continue
        inside += np.count_nonzero(w)
        if w.sum() > 0.0:
            normal = w @ g / w.sum()  # the mean gradient
            point = w @ (v + w[:, None] * g - w.max() / 2 * g) / w.sum()
            terms.append((w.max(), sign * normal, point))
    if not terms:
        return None
    rule = "vertex" if inside == 1 else "vertices"
    deepest = max(t[0] for t in terms)

    def along(d, g, p):  # one term: the overlap d |g| along g
        return d * np.linalg.norm(g), g / np.linalg.norm(g), p, rule, deepest

    if len(terms) == 1:
        return along(*terms[0])
    (d1, n1, p1), (d2, n2, p2) = terms
    s, w1, w2 = smooth_max_ref(d1, d2)
    if w2 == 0.0 or w1 == 0.0:
        return along(*terms[0]) if w2 == 0.0 else along(*terms[1])
    force = w1 * n1 + w2 * n2
    def cross(u, v):
        return u[0] * v[1] - u[1] * v[0]

    moment = w1 * cross(p1, n1) + w2 * cross(p2, n2)
    c = (w1 * p1 + w2 * p2) / (w1 + w2)
    # the point of the line of action {p : p x force = moment} nearest c
    t = np.array([-force[1], force[0]]) / np.linalg.norm(force)
    reach = np.linalg.norm(p1 - p2)
    lam = np.clip((moment - cross(c, force)) / cross(t, force), -reach, reach)
    return (s * np.linalg.norm(force), force / np.linalg.norm(force), c + lam * t,
            "blend-" + rule, deepest)


def depths_ref(geo, sa, sb, dim, pos, rot):
    """(d1, d2) of bodies 0 and 1 by linprog."""
    _, fa = world(geo, sa, dim, pos, rot, 0)
    _, fb = world(geo, sb, dim, pos, rot, 1)
    return -np.array([deepest_ref(fb, fa)[0], deepest_ref(fa, fb)[0]])


def closest_ref(p, verts, tris, dim):
    """Closest point of a polytope's boundary to p: face by face, then edge by edge."""
    best, q = np.inf, None
    edges = ([(i, (i + 1) % len(verts)) for i in range(len(verts))] if dim == 2 else
             [(t[i], t[(i + 1) % 3]) for t in tris for i in range(3)])
    for i, j in edges:
        e = verts[j] - verts[i]
        c = verts[i] + np.clip((p - verts[i]) @ e / (e @ e), 0.0, 1.0) * e
        if np.linalg.norm(p - c) < best:
            best, q = np.linalg.norm(p - c), c
    for t in tris if dim == 3 else []:  # projection into a triangle's interior
        a, b, c = verts[t]
        n = np.cross(b - a, c - a)
        n /= np.linalg.norm(n)
        x = p - (p - a) @ n * n
        lam = np.linalg.solve(np.column_stack([b - a, c - a, n]), x - a)
        if lam[0] >= 0 and lam[1] >= 0 and lam[0] + lam[1] <= 1 and abs((p - a) @ n) < best:
            best, q = abs((p - a) @ n), x
    return q


def contact(dim, sa, sb, pos, rot, geo, shift=(0.0, 0.0, 0.0), a=0, b=1):
    out = polytope_contact(dim, sa, a, sb, b, *map(float, shift), pos, rot, geo)
    return out[0], np.array(out[1:1 + dim]), np.array(out[4:4 + dim])


def touching_distance(fa, fb, u):
    """Largest s with A meeting B moved by s u (world faces, B at its place for s = 0)."""
    d = len(u)
    a = np.vstack([np.column_stack([fa[:, :d], np.zeros(len(fa))]),
                   np.column_stack([fb[:, :d], -fb[:, :d] @ u])])
    b = np.concatenate([fa[:, d], fb[:, d]])
    res = linprog(-np.eye(d + 1)[d], A_ub=a, b_ub=b, bounds=[(None, None)] * (d + 1),
                  method="highs")
    return res.x[d]


def random_pose(dim, rng, geo, sa, sb, approach):
    """Random orientations; B moved from A's centre along a random direction to where
    they touch, then back by ``approach`` times the smaller body size (< 0: apart)."""
    rot = random_rot(dim, rng, 2)
    u = rng.normal(size=dim)
    u /= np.linalg.norm(u)
    pos = np.array([rng.uniform(-1, 1, dim)] * 2)
    _, fa = world(geo, sa, dim, pos, rot, 0)
    _, fb = world(geo, sb, dim, pos, rot, 1)
    size = min(geo[1][sa] * geo[8][sa], geo[1][sb] * geo[8][sb])
    pos[1] += (touching_distance(fa, fb, u) - approach * size) * u
    return pos, rot


def overlapping_pose(dim, rng, geo, sa, sb):
    """A random pose overlapping by up to about a fifth of the smaller body."""
    return random_pose(dim, rng, geo, sa, sb, rng.uniform(0.002, 0.2))


# --------------------------------------------------------------------------- hand values
def test_square_corner_into_face():
    geo = table([box_rows([0.5, 0.5])])
    delta = 0.01
    pos = np.array([[0.1, 0.5 + np.sqrt(0.5) - delta], [0.0, 0.0]])
    rot = np.array([[np.pi / 4], [0.0]])  # A stands on a corner above B
    ov, n, c = contact(2, 0, 0, pos, rot, geo)
    assert ov == pytest.approx(delta, abs=1e-14)
    np.testing.assert_allclose(n, [0.0, -1.0], atol=1e-14)
    np.testing.assert_allclose(c, [0.1, 0.5 - delta / 2], atol=1e-14)


def test_cube_corner_into_face():
    geo = table([box_rows([0.5, 0.5, 0.5])])
    delta = 0.02
    # turn the (-1, -1, -1) corner straight down
    r = Rotation.align_vectors([[0.0, 0.0, -1.0]], [[-1.0, -1.0, -1.0]])[0]
    pos = np.array([[0.1, -0.2, 0.5 + SQ3 / 2 - delta], [0.0, 0.0, 0.0]])
    rot = np.array([np.roll(r.as_quat(), 1), [1.0, 0.0, 0.0, 0.0]])
    ov, n, c = contact(3, 0, 0, pos, rot, geo)
    assert ov == pytest.approx(delta, abs=1e-13)
    np.testing.assert_allclose(n, [0.0, 0.0, -1.0], atol=1e-13)
    np.testing.assert_allclose(c, [0.1, -0.2, 0.5 - delta / 2], atol=1e-13)


@pytest.mark.parametrize("dim", [2, 3])
def test_face_on_face_offset(dim):
    """A's bottom overhangs B's top face. 2D: A's corner inside B (x = -0.1) and B's
    inside A (x = 0.5) are equally deep, and the point is their mean, the overlap's
    centre; the arcs' normals are the faces' but for the short side faces on them,
    which tilt them by (delta / L)^4 (L = 0.6 m, the overlap's width) and deepen them
    by (delta / L)^3. 3D: no corner of B is inside A, and A's corners inside B give the
    overlap and the normal; the point is the centroid of the overlap (a patch: its
    volume over the overlap cubed is far above PATCH_TO squared), like 2D's."""
    h = [0.4, 0.3, 0.5][:dim]
    geo = table([box_rows(h), box_rows([0.5] * dim)])
    delta = 0.01
    pos = np.zeros((2, dim))
    pos[0, 0], pos[0, -1] = 0.3, 0.5 + h[-1] - delta
    if dim == 3:
        pos[0, 1] = 0.1
    rot = np.zeros((2, 1)) if dim == 2 else np.tile([1.0, 0.0, 0.0, 0.0], (2, 1))
    ov, n, c = contact(dim, 0, 1, pos, rot, geo)
    tilt = (delta / 0.6) ** 4 if dim == 2 else 0.0
    # 2D: a tie of the smooth maximum, S = (1 + BLEND / 4) delta, times its gradient's
    # length, 1 + BLEND / 4 (module notes)
    assert ov == pytest.approx(delta * (1 + BLEND / 4) ** 2 if dim == 2 else delta,
                               rel=1.01 * tilt * 0.6 / delta, abs=1e-14)
    np.testing.assert_allclose(n, -np.eye(dim)[-1], atol=1.01 * tilt + 1e-14)
    expect = np.array([0.2, 0.1, 0.5 - delta / 2])  # x in -0.1 .. 0.5, y -0.2 .. 0.4
    np.testing.assert_allclose(c, expect[[0, 2]] if dim == 2 else expect,
                               atol=tilt * 0.6 + 1e-14)
    if dim == 2:
        ov_ref, n_ref, c_ref, _ = contact_ref(geo, 0, 1, dim, pos, rot)
        assert ov == pytest.approx(ov_ref, abs=1e-15)
        np.testing.assert_allclose(n, n_ref, atol=1e-15)
        np.testing.assert_allclose(c, c_ref, atol=1e-15)


@pytest.mark.parametrize("dim", [2, 3])
def test_stacked_boxes_touch_at_the_face_centre(dim):
    """A small box resting on a big one: the contact point is under its centre, either
    way round."""
    geo = table([box_rows([0.3] * dim), box_rows([1.0] * dim)])
    delta = 1e-3
    pos = np.zeros((2, dim))
    pos[0, 0], pos[0, -1] = 0.2, 1.3 - delta
    rot = np.zeros((2, 1)) if dim == 2 else np.tile([1.0, 0.0, 0.0, 0.0], (2, 1))
    expect = np.zeros(dim)
    expect[0], expect[-1] = 0.2, 1.0 - delta / 2
    for a, b, sign in ((0, 1, 1.0), (1, 0, -1.0)):
        ov, n, c = contact(dim, a, b, pos[[a, b]], rot, geo)
        assert ov == pytest.approx(delta, abs=1e-14)
        np.testing.assert_allclose(n, -sign * np.eye(dim)[-1], atol=1e-14)
        np.testing.assert_allclose(c, expect, atol=1e-14)


def crossed_cubes(lift, slide=0.0, turn=0.0):
    """Two unit cubes, A above B: A's lowest feature an edge along x (turned by ``turn``
    about z), B's highest an edge along y; A lifted by ``lift`` from the touching
    height and slid by ``slide`` along its edge."""
    ra = Rotation.from_euler("xz", [45, turn], degrees=True)
    rb = Rotation.from_euler("y", 45, degrees=True)
    rot = np.array([np.roll(ra.as_quat(), 1), np.roll(rb.as_quat(), 1)])
    edge = ra.apply([1.0, 0.0, 0.0])
    pos = np.array([[*(slide * edge[:2]), np.sqrt(2.0) + lift], [0.0, 0.0, 0.0]])
    return pos, rot, edge


def test_crossed_edges():
    """Two cubes edge on crossed edge, pressed delta into each other: the overlap is
    delta (the distance between the edge lines: the penetration depth, where the SDF
    optima would give delta / sqrt(2) from two tied faces), the normal the edges' cross
    product from A to B, the point midway between the edges; either way round."""
    geo = table([box_rows([0.5, 0.5, 0.5])])
    for turn in (0.0, 30.0):
        for lift in (0.01, -0.01):
            pos, rot, edge = crossed_cubes(lift, turn=turn)
            ov, n, c = contact(3, 0, 0, pos, rot, geo)
            ov2, n2, c2 = contact(3, 0, 0, pos[::-1].copy(), rot[::-1].copy(), geo)
            if lift > 0:
                assert ov <= 0.0 and ov2 <= 0.0
                continue
            cross = np.cross(edge, [0.0, 1.0, 0.0])
            cross *= -np.sign(cross[2]) / np.linalg.norm(cross)  # downwards: A to B
            assert ov == pytest.approx(-lift, abs=1e-14)
            np.testing.assert_allclose(n, cross, atol=1e-14)
            np.testing.assert_allclose(c, [0.0, 0.0, np.sqrt(0.5) + lift / 2], atol=1e-14)
            assert ov2 == pytest.approx(ov, abs=1e-14)
            np.testing.assert_allclose(n2, -n, atol=1e-14)
            np.testing.assert_allclose(c2, c, atol=1e-14)


def test_edge_sliding_along_edge():
    """A's lowest edge slides along its length over B's top edge (crossed cubes pressed
    delta): while the edges cross well inside their lengths the edge pair gives ov =
    delta, the normal straight down; near the end of A's edge the face of B beside its
    end vertex takes over at the same overlap, and past the end that vertex stays under
    that face. The overlap is one continuous function of the slide s, the penetration
    depth min(delta, (h + delta - s) / sqrt(2))."""
    h, delta = 0.5, 0.01
    geo = table([box_rows([h] * 3)])
    face = -np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)  # -(B's face beside the vertex)
    for s in np.linspace(0.0, h + 0.9 * delta, 301):
        pos, rot, _ = crossed_cubes(-delta, slide=s)
        ov, n, c = contact(3, 0, 0, pos, rot, geo)
        by_face = (h + delta - s) / np.sqrt(2.0)
        assert ov == pytest.approx(min(delta, by_face), abs=1e-14)
        if delta < by_face - 1e-9:
            np.testing.assert_allclose(n, [0.0, 0.0, -1.0], atol=1e-14)
            np.testing.assert_allclose(c, [0.0, 0.0, np.sqrt(0.5) - delta / 2],
                                       atol=1e-14)
        elif by_face < delta - 1e-9:
            np.testing.assert_allclose(n, face, atol=1e-14)


@pytest.mark.parametrize("dim", [2, 3])
def test_tilted_box_on_box_point_moves_continuously(dim):
    """A small box on a big one, tilted through the flat position: the overlap is the
    deepest corner's and the point slides continuously from under one end to under the
    other (2D: the depth-weighted mean of the corners through; 3D: the centroid of the
    intersection, a patch), where jumping between tied corners would make a resting box
    chatter."""
    hx, hz, delta = 0.3, 0.1, 1e-3
    geo = table([box_rows([hx, hz] if dim == 2 else [hx, 0.2, hz]), box_rows([1.0] * dim)])
    pos = np.zeros((2, dim))
    pos[0, 0], pos[0, -1] = 0.1, 1.0 + hz - delta
    points = []
    for a in np.linspace(-2.0, 2.0, 401) * delta / hx:
        rot = (np.array([[a], [0.0]]) if dim == 2 else np.array(
            [np.roll(Rotation.from_euler("y", -a).as_quat(), 1), [1.0, 0.0, 0.0, 0.0]]))
        ov, n, c = contact(dim, 0, 1, pos, rot, geo)
        low = world(geo, 0, dim, pos, rot, 0)[0][:, -1].min()
        assert ov == pytest.approx(1.0 - low, abs=1e-14)
        np.testing.assert_allclose(n, -np.eye(dim)[-1], atol=1e-14)
        assert c[-1] == pytest.approx(1.0 - ov / 2, abs=1e-14)
        points.append(c)
        if dim == 3:
            np.testing.assert_allclose(c, contact_ref(geo, 0, 1, 3, pos, rot)[2],
                                       atol=1e-12)
        elif abs(a) == 2.0 * delta / hx:  # one end through: the middle of its corners
            x = pos[0, 0] - np.sign(a) * (hx * np.cos(a) - hz * np.sin(abs(a)))
            assert c[0] == pytest.approx(x, abs=1e-14)
    points = np.array(points)
    np.testing.assert_allclose(points[200, :-1], pos[0, :-1], atol=1e-14)  # flat
    assert np.linalg.norm(np.diff(points, axis=0), axis=1).max() < 0.02 * hx


def test_staggered_squares_point_moves_continuously():
    """2D: a square on a square, staggered, turned through parallel. Each has one corner
    inside the other; the deeper one carries the point (the energy's gradient) until
    their depths are within BLEND of each other, and across that band (the smooth
    maximum) the point slides from one corner to the other, through the overlap's
    centre when the faces are parallel. Jumping from corner to corner is what made
    staggered polygons rock and never settle."""
    h, delta = 0.01, 2e-4
    geo = table([box_rows([h, h]), box_rows([h, h])])
    pos = np.array([[0.006, 3 * h - delta], [0.0, h]])
    xs = []
    for a in np.linspace(-0.02, 0.02, 801):
        ov, n, c = contact(2, 0, 1, pos, np.array([[a], [0.0]]), geo)
        ov_ref, n_ref, c_ref, _ = contact_ref(geo, 0, 1, 2, pos, np.array([[a], [0.0]]))
        assert ov == pytest.approx(ov_ref, abs=1e-15)
        np.testing.assert_allclose(c, c_ref, atol=1e-15)
        xs.append(c[0])
        if a == 0.0:  # the overlap spans x = -0.004 (A's corner) .. 0.01 (B's)
            assert c == pytest.approx([0.003, 2 * h - delta / 2], abs=1e-15)
    xs = np.array(xs)
    corner_a = pos[0, 0] - h * np.cos(0.02) + h * np.sin(0.02)  # A's lower left
    assert xs[0] == pytest.approx(h, abs=1e-5) and xs[-1] == pytest.approx(corner_a)
    assert np.abs(np.diff(xs)).max() < 0.01 * (xs[0] - xs[-1])


def test_staggered_cubes_point_moves_continuously():
    """3D: a cube on a cube, staggered along the diagonal, turned through parallel about
    the other diagonal. Each has one corner inside the other, and the deeper one gives
    the overlap; the overlap is a patch, so the point is the centroid of the bodies'
    intersection, which slides from one corner's side to the other's, through the
    overlap's centre when the faces are parallel. The deeper side's corners alone
    jumped it across the overlap in one step (and a cube packing never came to rest)."""
    h, delta = 0.01, 2e-4
    geo = table([box_rows([h] * 3)])
    pos = np.array([[0.006, 0.006, 2 * h - delta], [0.0, 0.0, 0.0]])
    axis = np.array([1.0, -1.0, 0.0]) / np.sqrt(2.0)
    xs = []
    for a in np.linspace(-0.02, 0.02, 801):
        q = np.roll(Rotation.from_rotvec(a * axis).as_quat(), 1)
        rot = np.array([q, [1.0, 0.0, 0.0, 0.0]])
        ov, n, c = contact(3, 0, 0, pos, rot, geo)
        ov_ref, n_ref, c_ref, rule = contact_ref(geo, 0, 0, 3, pos, rot)
        assert rule.startswith("patch-")
        assert ov == pytest.approx(ov_ref, abs=1e-15)
        np.testing.assert_allclose(n, n_ref, atol=1e-13)
        np.testing.assert_allclose(c, c_ref, atol=1e-12 * h)
        xs.append(c[:2])
        if a == 0.0:  # the overlap spans -0.004 (A's corner) .. 0.01 (B's) each way
            assert ov == pytest.approx(delta, rel=1e-12)
            np.testing.assert_allclose(n, [0.0, 0.0, -1.0], atol=1e-15)
            np.testing.assert_allclose(c, [0.003, 0.003, h - delta / 2], atol=1e-15)
    xs = np.array(xs) @ np.array([1.0, 1.0]) / np.sqrt(2.0)  # along the stagger
    travel = abs(xs[0] - xs[-1])
    corners = 0.014 * np.sqrt(2.0)  # how far the deeper side's corners jumped it
    assert travel > 0.15 * corners  # towards the deeper end, either way
    assert np.abs(np.diff(xs)).max() < 0.002 * corners


def test_equal_boxes_stacked_in_line_push_straight_apart():
    """Two equal squares, one 1 mm into the other, their sides in line or offset by
    less than the overlap: each one's lower (upper) corners lie nearer the other's side
    faces than its top (bottom), so the nearest faces would give a sideways or a
    45-degree normal. The corners take the faces their arcs run along (the side faces'
    short pieces weigh in by their lengths to the fourth): the normal is vertical
    within (delta / w)^4, the overlap that of two staggered faces, the point the
    overlap's centre."""
    geo = table([box_rows([0.1, 0.1])])
    delta = 1e-3
    for dx in (0.0, 1e-9, -1e-9, 1e-6, -1e-6, 5e-4, 1e-3, 2e-3):
        pos = np.array([[0.5 + dx, 0.6 - delta], [0.5, 0.4]])
        ov, n, c = contact(2, 0, 0, pos, np.zeros((2, 1)), geo)
        assert ov == pytest.approx(delta * (1 + BLEND / 4) ** 2, rel=1e-12)
        np.testing.assert_allclose(n, [0.0, -1.0], atol=2.0 * (delta / 0.2) ** 4)
        np.testing.assert_allclose(c, [0.5 + dx / 2, 0.5 - delta / 2], atol=1e-13)
        ov_ref, n_ref, c_ref, _ = contact_ref(geo, 0, 0, 2, pos, np.zeros((2, 1)))
        assert ov == pytest.approx(ov_ref, abs=1e-15)
        np.testing.assert_allclose(n, n_ref, atol=1e-15)
        np.testing.assert_allclose(c, c_ref, atol=1e-15)


def test_corner_sliding_off_a_corner_turns_the_normal_continuously():
    """A square's corner, 2 mm into a box's top face, slides sideways past the box's
    top corner and off. The normal turns from the top face's through the bisector (the
    two corners at each other) to the square's side face, at no more than 0.05 rad per
    5 um of slide (a nearest-face rule turned it by 90 degrees at once: 1.41), and the
    overlap moves by no more than 10 times the slide."""
    geo = table([box_rows([0.05, 0.05]), box_rows([0.2, 0.1])])
    tip, d = 0.05 * np.sqrt(2.0), 2e-3
    rot = np.array([[np.pi / 4], [0.0]])
    xs = np.linspace(0.19, 0.21, 4001)
    ovs, ns = [], []
    for x in xs:
        pos = np.array([[x, 0.1 + tip - d], [0.0, 0.0]])
        ov, n, c = contact(2, 0, 1, pos, rot, geo)
        if ov <= 0.0:
            break
        ovs.append(ov)
        ns.append(n)
        if x in (0.19, 0.2):
            ov_ref, n_ref, c_ref, _ = contact_ref(geo, 0, 1, 2, pos, rot)
            assert ov == pytest.approx(ov_ref, abs=1e-15)
            np.testing.assert_allclose(n, n_ref, atol=1e-14)
            np.testing.assert_allclose(c, c_ref, atol=1e-15)
    ovs, ns = np.array(ovs), np.array(ns)
    assert xs[len(ovs)] == pytest.approx(0.2 + d, abs=1e-5)  # off: 2 mm past the corner
    assert ovs[0] == pytest.approx(d, rel=1e-12)
    np.testing.assert_allclose(ns[0], [0.0, -1.0], atol=1e-15)
    np.testing.assert_allclose(ns[2000], -np.sqrt([0.5, 0.5]), atol=1e-12)  # x = 0.2
    np.testing.assert_allclose(ns[-1], -np.sqrt([0.5, 0.5]), atol=1e-12)
    assert np.linalg.norm(np.diff(ns, axis=0), axis=1).max() < 0.05  # measured 0.042
    assert np.abs(np.diff(ovs)).max() < 10 * (xs[1] - xs[0])  # measured 8.4


def test_corner_pushed_through_a_plank_keeps_pushing_back():
    """2D: a square's corner pushed through a plank 40 mm thick. Past the plank's middle
    the corner is nearer the far face, its own depth falls and its normal turns over;
    the programme's depth (the plank deep in the square's corner) takes over within a
    tenth of the corner's depth, so the overlap keeps growing and the normal keeps
    pushing the square back, where the corners alone would let it fall through. Within
    1 mm past the middle the two are blended and the normal points the wrong way."""
    geo = table([box_rows([0.05, 0.05]), box_rows([0.5, 0.02])])
    tip = 0.05 * np.sqrt(2.0)
    rot = np.array([[np.pi / 4], [0.0]])
    ys = np.linspace(0.019, -0.05, 691)  # the corner's height, the plank at |y| < 0.02
    ovs, ns = [], []
    for y in ys:
        pos = np.array([[0.01, y + tip], [0.0, 0.0]])
        ov, n, c = contact(2, 0, 1, pos, rot, geo)
        # (the point is not compared: past the middle the deepest point of the square
        # in the plank is any of a segment on the plank's mid-line)
        assert ov == pytest.approx(contact_ref(geo, 0, 1, 2, pos, rot)[0], abs=1e-14)
        ovs.append(ov)
        ns.append(n)
    ovs, ns = np.array(ovs), np.array(ns)
    window = (ys < 0.0) & (ys > -0.001)
    assert np.all(ns[~window, 1] < -0.999)  # pushing the square back up
    assert np.all(ovs >= 0.97 * np.maximum.accumulate(ovs))
    assert np.abs(np.diff(ovs)).max() < 3e-4  # steps of 1e-4 in y
    assert ovs[-1] == pytest.approx(0.07 / np.sqrt(2.0), rel=1e-12)  # P2: the plank in A


def moved_overlap(geo, sa, sb, pos, rot, dx, dtheta):
    """The overlap with body 1 (B) moved by ``dx`` and turned by the rotation vector
    ``dtheta`` about its centre (3D)."""
    p, r = pos.copy(), rot.copy()
    p[1] += dx
    turned = Rotation.from_rotvec(dtheta) * Rotation.from_quat(np.roll(rot[1], -1))
    r[1] = np.roll(turned.as_quat(), 1)
    return contact(3, sa, sb, p, r, geo)[0]


def test_force_is_minus_gradient_of_overlap_energy():
    """For one vertex on a face and for one edge on an edge (3D, random shallow poses),
    the force kn ov n on B at the point c is minus the gradient of kn ov^2 / 2 with
    respect to B's rigid motion, i.e. d ov = -(n . dx + ((c - x_B) x n) . dtheta): the
    contact is conservative. Central differences; B turned about its centre."""
    rng = np.random.default_rng(80)
    geo = random_table(3, rng)
    counts = {"vertex": 0, "sat-vertex": 0, "sat-edge": 0}
    for _ in range(100):
        sa, sb = rng.integers(0, 5, 2)
        pos, rot = random_pose(3, rng, geo, sa, sb, rng.uniform(0.002, 0.02))
        _, n, c = contact(3, sa, sb, pos, rot, geo)
        rule = contact_ref(geo, sa, sb, 3, pos, rot)[3]
        if rule not in counts:
            continue  # separated, or several vertices (a distributed support)
        counts[rule] += 1
        size = geo[1][sb] * geo[8][sb]
        u, w = rng.normal(size=3), rng.normal(size=3) / size
        eps = 1e-6 * size
        slope = (moved_overlap(geo, sa, sb, pos, rot, eps * u, eps * w)
                 - moved_overlap(geo, sa, sb, pos, rot, -eps * u, -eps * w)) / (2.0 * eps)
        expect = -(n @ u + np.cross(c - pos[1], n) @ w)
        assert slope == pytest.approx(expect, abs=1e-6 * (1.0 + abs(expect)))
    assert counts["vertex"] >= 10 and counts["sat-edge"] >= 10, counts


# --------------------------------------------------------------------------- random poses
@pytest.mark.parametrize("dim", [2, 3])
def test_random_pairs_match_references(dim):
    """Overlaps up to a fifth of the smaller body. Where the deeper optimum is a vertex
    (and always in 2D): the linear programme's overlap and normal, the depth-weighted
    point. Elsewhere (3D, an edge across an edge): never below the penetration depth of
    the separating-axis reference, which the next test shows reached exactly for
    shallower overlaps."""
    rng = np.random.default_rng(10 + dim)
    geo = random_table(dim, rng)
    rules = set()
    for _ in range(120):
        sa, sb = rng.integers(0, 5, 2)
        pos, rot = overlapping_pose(dim, rng, geo, sa, sb)
        ov, n, c = contact(dim, sa, sb, pos, rot, geo)
        ov_ref, n_ref, c_ref, rule = contact_ref(geo, sa, sb, dim, pos, rot)
        rules.add(rule)
        size = geo[1][sa] * geo[8][sa]
        if rule.startswith("sat"):
            assert ov >= ov_ref - 1e-12 * size
            assert ov >= depths_ref(geo, sa, sb, dim, pos, rot).max() - 1e-12 * size
            continue
        assert ov == pytest.approx(ov_ref, abs=1e-12 * size)
        np.testing.assert_allclose(n, n_ref, atol=1e-10)
        np.testing.assert_allclose(c, c_ref, atol=1e-11 * size)
    assert {"vertex", "vertices"} <= rules


@pytest.mark.parametrize("seed", [0, 1])
def test_edge_pairs_match_separating_axes(seed):
    """3D, overlaps up to 2 % of the smaller body: every contact, the separating-axis
    ones included (an edge across an edge, or the vertex and face beside it), matches
    the reference: overlap, normal and point."""
    rng = np.random.default_rng(90 + seed)
    geo = random_table(3, rng)
    rules = {}
    for _ in range(150):
        sa, sb = rng.integers(0, 5, 2)
        pos, rot = random_pose(3, rng, geo, sa, sb, rng.uniform(0.0005, 0.02))
        ov, n, c = contact(3, sa, sb, pos, rot, geo)
        ov_ref, n_ref, c_ref, rule = contact_ref(geo, sa, sb, 3, pos, rot)
        rules[rule] = rules.get(rule, 0) + 1
        size = geo[1][sa] * geo[8][sa]
        assert ov == pytest.approx(ov_ref, abs=1e-12 * size)
        np.testing.assert_allclose(n, n_ref, atol=1e-10)
        np.testing.assert_allclose(c, c_ref, atol=1e-11 * size)
    assert rules.get("sat-edge", 0) > 20, rules


@pytest.mark.parametrize("dim", [2, 3])
def test_swap_symmetry(dim):
    rng = np.random.default_rng(20 + dim)
    geo = random_table(dim, rng)
    for _ in range(100):
        sa, sb = rng.integers(0, 5, 2)
        pos, rot = overlapping_pose(dim, rng, geo, sa, sb)
        ov, n, c = contact(dim, sa, sb, pos, rot, geo)
        ov2, n2, c2 = contact(dim, sb, sa, pos[::-1].copy(), rot[::-1].copy(), geo)
        if ov <= 0.0:
            assert ov2 <= 0.0
            continue
        if abs(np.ptp(depths_ref(geo, sa, sb, dim, pos, rot))) < 1e-9:
            continue  # d1 = d2 (congruent boxes): each order takes its own P1
        assert ov2 == pytest.approx(ov, abs=1e-12)
        np.testing.assert_allclose(n2, -n, atol=1e-10)
        np.testing.assert_allclose(c2, c, atol=1e-12)


@pytest.mark.parametrize("dim", [2, 3])
def test_rigid_motion_invariance(dim):
    rng = np.random.default_rng(30 + dim)
    geo = random_table(dim, rng)
    for _ in range(60):
        sa, sb = rng.integers(0, 5, 2)
        pos, rot = overlapping_pose(dim, rng, geo, sa, sb)
        ov, n, c = contact(dim, sa, sb, pos, rot, geo)
        if ov <= 0.0:
            continue
        move = rng.uniform(-5, 5, dim)
        if dim == 2:
            turn = rng.uniform(-np.pi, np.pi)
            q = rotation(2, np.array([[turn]]), 0)
            rot2 = rot + turn
        else:
            r = Rotation.random(random_state=rng)
            q = r.as_matrix()
            rot2 = np.roll((r * Rotation.from_quat(np.roll(rot, -1, axis=1))).as_quat(), 1,
                           axis=1).copy()
        ov2, n2, c2 = contact(dim, sa, sb, pos @ q.T + move, rot2, geo)
        assert ov2 == pytest.approx(ov, abs=1e-12)
        np.testing.assert_allclose(n2, q @ n, atol=1e-10)
        np.testing.assert_allclose(c2, q @ c + move, atol=1e-11)


@pytest.mark.parametrize("dim", [2, 3])
def test_periodic_shift(dim):
    rng = np.random.default_rng(40 + dim)
    geo = random_table(dim, rng)
    for _ in range(40):
        sa, sb = rng.integers(0, 5, 2)
        pos, rot = overlapping_pose(dim, rng, geo, sa, sb)
        shift = np.zeros(3)
        shift[:dim] = rng.integers(-2, 3, dim) * 7.5
        placed = pos.copy()
        placed[1] -= shift[:dim]  # B's image at the shift is where B was
        ov, n, c = contact(dim, sa, sb, placed, rot, geo, shift)
        ov2, n2, c2 = contact(dim, sa, sb, pos, rot, geo)
        assert ov == pytest.approx(ov2, abs=1e-12)
        if ov2 > 0.0:
            np.testing.assert_allclose(n, n2, atol=1e-12)
            np.testing.assert_allclose(c, c2, atol=1e-12)


@pytest.mark.parametrize("dim", [2, 3])
def test_separated_pairs(dim):
    """Bodies a little apart (from 1e-6 of their size), where for polyhedra the face
    axes alone often do not separate them, and far apart."""
    rng = np.random.default_rng(50 + dim)
    geo = random_table(dim, rng)
    for _ in range(60):
        sa, sb = rng.integers(0, 5, 2)
        pos, rot = random_pose(dim, rng, geo, sa, sb, -10.0 ** rng.uniform(-6, -1))
        assert contact(dim, sa, sb, pos, rot, geo)[0] <= 0.0
        assert contact(dim, sb, sa, pos[::-1].copy(), rot[::-1].copy(), geo)[0] <= 0.0
    far = np.array([[0.0] * dim, [10.0] + [0.0] * (dim - 1)])
    assert contact(dim, 0, 1, far, random_rot(dim, rng, 2), geo)[0] < 0.0


# --------------------------------------------------------------------------- spheres
def sphere_ref(p, ra, geo, s, dim, pos, rot, b):
    verts, faces = world(geo, s, dim, pos, rot, b)
    phi = np.max(faces[:, :dim] @ p - faces[:, dim])
    if phi > 0.0:
        tris = geo[7][geo[6][s]:geo[6][s + 1]]
        q = closest_ref(p, verts, tris, dim)
        n = (q - p) / np.linalg.norm(q - p)
        ov = ra - np.linalg.norm(q - p)
    else:
        k = np.argmax(faces[:, :dim] @ p - faces[:, dim])
        n, ov = -faces[k, :dim], ra - phi
    return ov, n, p + (ra - ov / 2) * n


@pytest.mark.parametrize("dim", [2, 3])
def test_sphere_polytope_and_box(dim):
    rng = np.random.default_rng(60 + dim)
    geo = random_table(dim, rng)
    for i in range(150):
        sb = i % 5
        rot = random_rot(dim, rng, 2)
        reach = geo[1][sb] * geo[8][sb]
        pos = np.array([rng.uniform(-1.2, 1.2, dim) * reach, rng.uniform(-1, 1, dim)])
        pos[0] += pos[1]
        ra = rng.uniform(0.05, 0.5)
        ref = sphere_ref(pos[0], ra, geo, sb, dim, pos, rot, 1)
        kernels = (sphere_polytope, sphere_box) if sb == 4 else (sphere_polytope,)
        for kern in kernels:
            out = kern(dim, 0, ra, sb, 1, 0.0, 0.0, 0.0, pos, rot, geo)
            assert out[0] == pytest.approx(ref[0], abs=1e-12)
            np.testing.assert_allclose(out[1:1 + dim], ref[1], atol=1e-10)
            np.testing.assert_allclose(out[4:4 + dim], ref[2], atol=1e-12)
        shifted = pos.copy()
        shifted[1] -= 3.0
        out = sphere_polytope(dim, 0, ra, sb, 1, 3.0, 3.0, 3.0 if dim == 3 else 0.0,
                              shifted, rot, geo)
        assert out[0] == pytest.approx(ref[0], abs=1e-12)


def test_sphere_sphere_and_plane():
    pos = np.array([[0.0, 0.0, 0.0], [0.0, 0.3, 0.4], [0.0, 0.0, -0.45]])
    normal = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    ov, nx, ny, nz, cx, cy, cz, _ = sphere_sphere(3, 0, 0.3, 1, 0.25, 0.0, 0.0, 0.0, pos)
    assert ov == pytest.approx(0.05)
    np.testing.assert_allclose([nx, ny, nz, cx, cy, cz], [0, 0.6, 0.8, 0, 0.165, 0.22])
    ov, nx, ny, nz, cx, cy, cz, _ = sphere_plane(3, 0, 0.5, 2, pos, normal)
    assert ov == pytest.approx(0.05)
    np.testing.assert_allclose([nx, ny, nz, cx, cy, cz], [0, 0, -1, 0, 0, -0.475])


# --------------------------------------------------------------------------- walls
@pytest.mark.parametrize("dim", [2, 3])
def test_polytope_plane_deepest_vertex(dim):
    """Overlap: the deepest vertex; point: ov/2 in front of the deepest level, on the
    normal through the depth-weighted mean of the vertices behind the wall (box_plane:
    the deepest vertex itself, which agrees when one vertex is through)."""
    rng = np.random.default_rng(70 + dim)
    geo = random_table(dim, rng)
    for i in range(50):
        s = i % 5
        pos = rng.uniform(-1, 1, (2, dim))
        rot = random_rot(dim, rng, 2)
        normal = np.zeros((2, dim))
        normal[1] = rng.normal(size=dim)
        normal[1] /= np.linalg.norm(normal[1])
        verts, _ = world(geo, s, dim, pos, rot, 0)
        depth = (verts - pos[1]) @ normal[1]
        k = np.argmin(depth)
        out = polytope_plane(dim, s, 0, 1, pos, rot, normal, geo)
        ov = -depth[k]
        if ov <= 0.0:
            assert out[0] <= 0.0
            continue
        assert out[0] == pytest.approx(ov, abs=1e-12)
        np.testing.assert_allclose(out[1:1 + dim], -normal[1], atol=1e-15)
        behind = depth < 0.0
        w = -depth[behind]
        mean = (w[:, None] * verts[behind]).sum(axis=0) / w.sum()
        dw = -(mean - pos[1]) @ normal[1]
        np.testing.assert_allclose(out[4:4 + dim], mean + (dw - ov / 2) * normal[1],
                                   atol=1e-12)
        if s == 4 and behind.sum() == 1:
            box = box_plane(dim, s, 0, 1, pos, rot, normal, geo)
            np.testing.assert_allclose(box[4:4 + dim], out[4:4 + dim], atol=1e-12)


@pytest.mark.parametrize("dim", [2, 3])
def test_box_landing_flat(dim):
    """A box lying flat on a wall touches at the middle of its face; on an edge (3D), at
    the middle of the edge: the tied corners are averaged."""
    geo = table([box_rows([0.5, 0.3, 0.2][:dim])])
    pos = np.zeros((2, dim))
    pos[0, -1] = 0.19
    pos[0, 0] = 0.7
    normal = np.zeros((2, dim))
    normal[1, -1] = 1.0
    rots = [np.zeros((2, 1))] if dim == 2 else [
        np.tile([1.0, 0.0, 0.0, 0.0], (2, 1)),
        np.array([np.roll(Rotation.from_euler("x", 30, degrees=True).as_quat(), 1),
                  [1.0, 0.0, 0.0, 0.0]])]
    for rot in rots:
        low = world(geo, 0, dim, pos, rot, 0)[0][:, -1].min()
        for kern in (polytope_plane, box_plane):
            out = kern(dim, 0, 0, 1, pos, rot, normal, geo)
            assert out[0] == pytest.approx(-low, abs=1e-14)
            expect = np.zeros(dim)
            expect[0], expect[-1] = 0.7, low / 2
            if dim == 3 and rot[0, 0] != 1.0:
                expect[1] = pos[0, 1] - 0.3 * np.cos(np.pi / 6) + 0.2 * np.sin(np.pi / 6)
            np.testing.assert_allclose(out[4:4 + dim], expect, atol=1e-14)
