"""Level-set shapes: SDFs against brute-force geometry, exact and numerical mass
properties against hand values and Monte Carlo, principal frames, table rows, errors."""

import math
import time

import numba
import numpy as np
import pytest
from scipy.spatial import ConvexHull, Delaunay, cKDTree
from scipy.spatial.transform import Rotation

from dem.shapes.box import Box
from dem.shapes.custom import CustomShape
from dem.shapes.polygon import ConvexPolygon
from dem.shapes.polyhedron import ConvexPolyhedron


@numba.njit
def sdf_sphere_user(x, y, z, p):
    """Sphere (disk in 2D) of radius p[0] centred at (p[1], p[2], 0)."""
    dx, dy = x - p[1], y - p[2]
    return math.sqrt(dx * dx + dy * dy + z * z) - p[0]


@numba.njit
def sdf_superellipsoid(x, y, z, p):
    """|x/a|^e + |y/b|^e + |z/c|^e <= 1 as a 1-Lipschitz level set (a, b, c, e) = p."""
    e = p[3]
    s = (abs(x / p[0]) ** e + abs(y / p[1]) ** e + abs(z / p[2]) ** e) ** (1.0 / e)
    return (s - 1.0) * min(p[0], min(p[1], p[2]))


@numba.njit
def sdf_rotated_box(x, y, z, p):
    """Box (1, 0.5, 0.25) rotated by p[0] about z, then about x by p[1], centred at
    (p[2], p[3], 0): not in its principal frame."""
    x, y = x - p[2], y - p[3]
    c, s = math.cos(p[1]), math.sin(p[1])  # undo the rotation about x
    y, z = c * y + s * z, -s * y + c * z
    c, s = math.cos(p[0]), math.sin(p[0])  # undo the rotation about z
    x, y = c * x + s * y, -s * x + c * y
    qx, qy, qz = abs(x) - 1.0, abs(y) - 0.5, abs(z) - 0.25
    out = math.sqrt(max(qx, 0.0) ** 2 + max(qy, 0.0) ** 2 + max(qz, 0.0) ** 2)
    return out + min(max(qx, max(qy, qz)), 0.0)


def random_polygon(rng, n=12):
    return ConvexPolygon(rng.normal(size=(n, 2)) * [1.0, 0.6] + [0.3, -0.2])


def random_polyhedron(rng, n=25):
    points = rng.normal(size=(n, 3)) * [1.0, 0.7, 0.5] + 0.2
    return ConvexPolyhedron.from_vertices(points)


# --- brute force references -----------------------------------------------------


def boundary_samples_2d(vertices, spacing):
    """Points along the edges of a closed polygon, no farther than ``spacing`` apart."""
    pts = []
    for a, b in zip(vertices, np.roll(vertices, -1, axis=0), strict=True):
        n = int(np.ceil(np.linalg.norm(b - a) / spacing))
        t = np.arange(n)[:, None] / n
        pts.append(a + t * (b - a))
    return np.vstack(pts)


def boundary_samples_3d(vertices, tris, spacing):
    """Lattice points on triangles: every surface point is within ``spacing`` of one."""
    pts = []
    for a, b, c in vertices[tris]:
        n = int(np.ceil(max(np.linalg.norm(b - a), np.linalg.norm(c - a),
                            np.linalg.norm(c - b)) / spacing))
        i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
        keep = i + j <= n
        u, v = i[keep][:, None] / n, j[keep][:, None] / n
        pts.append(a + u * (b - a) + v * (c - a))
    return np.vstack(pts)


def brute_sdf(shape, boundary, spacing, x):
    """|sdf| from the nearest boundary sample, sign from an independent hull test.

    Returns the brute-force signed distance and a mask of points farther than
    ``spacing`` from the boundary (where the sign test is unambiguous).
    """
    dist = cKDTree(boundary).query(x)[0]
    eq = ConvexHull(shape.vertices).equations  # qhull's own facets: n . x + d <= 0
    inside = (x @ eq[:, :-1].T + eq[:, -1] <= 0.0).all(axis=1)
    return np.where(inside, -dist, dist), dist > spacing


def sample_points(rng, shape, m):
    """Uniform points in the shape's bounding box grown by 30 % on each side."""
    v = shape.corners() if isinstance(shape, Box) else shape.vertices
    lo, hi = v.min(axis=0), v.max(axis=0)
    pad = 0.3 * (hi - lo)
    return rng.uniform(lo - pad, hi + pad, size=(m, shape.dim))


# --- SDF ------------------------------------------------------------------------


@pytest.mark.parametrize("dim", [2, 3])
def test_box_sdf_equals_polygon_and_polyhedron_sdf(dim):
    rng = np.random.default_rng(1)
    box = Box([1.0, 0.5, 0.25][:dim])
    other = ConvexPolygon(box.corners()) if dim == 2 else \
        ConvexPolyhedron.from_vertices(box.corners())
    x = sample_points(rng, box, 4000)
    np.testing.assert_allclose(other.sdf(x), box.sdf(x), rtol=0.0, atol=1e-12)


@pytest.mark.parametrize("kind", ["box2", "box3", "polygon", "polyhedron", "prism",
                                  "fine"])
def test_sdf_against_brute_force(kind):
    rng = np.random.default_rng(2)
    if kind == "box2":
        shape, hull = Box([0.8, 0.3]), None
    elif kind == "box3":
        shape, hull = Box([0.8, 0.3, 0.5]), None
    elif kind == "polygon":
        shape = hull = random_polygon(rng)
    elif kind == "polyhedron":
        shape = hull = random_polyhedron(rng)
    elif kind == "prism":
        shape = hull = ConvexPolyhedron.extrude(ConvexPolygon.regular(7, 0.6), 0.4)
    else:  # many small faces: a 300-vertex polytope close to the unit sphere
        v = rng.normal(size=(300, 3))
        v /= np.linalg.norm(v, axis=1)[:, None]
        shape = hull = ConvexPolyhedron.from_vertices(v)
    if hull is None:  # boxes: brute force on the corners' hull, built independently
        corners = shape.corners()
        hull = ConvexPolygon(corners) if shape.dim == 2 else \
            ConvexPolyhedron.from_vertices(corners)
    if shape.dim == 2:
        spacing = 2e-4
        boundary = boundary_samples_2d(hull.vertices, spacing)
    else:
        spacing = 0.02
        boundary = boundary_samples_3d(hull.vertices, hull.triangles, spacing)
    assert 1e4 < len(boundary) < 1e6
    x = sample_points(rng, shape, 3000)
    brute, clear = brute_sdf(hull, boundary, spacing, x)
    sdf = shape.sdf(x)
    # sampled distances overestimate by at most the lattice spacing, never underestimate
    assert np.all(np.abs(sdf) <= np.abs(brute) + 1e-12)
    assert np.all(np.abs(brute) - np.abs(sdf) <= spacing)
    assert np.all(np.sign(sdf[clear]) == np.sign(brute[clear]))
    assert clear.sum() > 2500 and (sdf < 0).sum() > 100


def test_sdf_single_point_and_batch_agree():
    shape = random_polyhedron(np.random.default_rng(3))
    x = np.array([[0.1, 0.2, 0.3], [3.0, -1.0, 0.5]])
    assert isinstance(shape.sdf(x[1]), float)
    assert shape.sdf(x[1]) == shape.sdf(x)[1]
    with pytest.raises(ValueError, match=r"shape \(m, 3\)"):
        shape.sdf(np.zeros((4, 2)))


@pytest.mark.parametrize("kind", ["box2", "box3", "polygon", "polyhedron"])
def test_sdf_gradient_has_unit_length_off_the_medial_axis(kind):
    rng = np.random.default_rng(4)
    shape = {"box2": lambda: Box([0.8, 0.3]), "box3": lambda: Box([0.8, 0.3, 0.5]),
             "polygon": lambda: random_polygon(rng),
             "polyhedron": lambda: random_polyhedron(rng)}[kind]()
    dim, eps = shape.dim, 1e-6
    x = sample_points(rng, shape, 2000)
    if isinstance(shape, Box):
        values = np.abs(x) - shape.half_extents
    else:
        values = x @ shape.normals.T - shape.offsets
    top2 = np.sort(values, axis=1)[:, -2:]
    sdf = shape.sdf(x)
    # outside a convex set the distance is smooth; inside, stay off face bisectors
    keep = (np.abs(sdf) > 1e-3) & ((sdf > 0) | (top2[:, 1] - top2[:, 0] > 1e-3))
    grad = np.stack([(shape.sdf(x + eps * e) - shape.sdf(x - eps * e)) / (2 * eps)
                     for e in np.eye(dim)], axis=1)
    assert keep.sum() > 1000
    np.testing.assert_allclose(np.linalg.norm(grad[keep], axis=1), 1.0, atol=1e-6)


def test_custom_sdf_evaluates_the_user_function_in_the_moved_frame():
    shape = CustomShape(sdf_rotated_box, 1.5, 3, params=[0.4, 0.7, 0.2, -0.1])
    body, rot, c = shape.principal()
    x = np.random.default_rng(5).uniform(-1.5, 1.5, size=(500, 3))
    expected = shape.sdf(x @ rot.T + c)
    np.testing.assert_allclose(body.sdf(x), expected, atol=1e-12)
    big = body.scaled(2.0)
    np.testing.assert_allclose(big.sdf(2.0 * x), 2.0 * body.sdf(x), atol=1e-12)


# --- exact mass properties --------------------------------------------------------


def test_box_mass_properties_are_analytic():
    rho, (a, b, c) = 2500.0, (2.0, 1.0, 0.5)  # full side lengths
    m, centroid, inertia = Box([a / 2, b / 2, c / 2]).mass_properties(rho)
    assert m == pytest.approx(rho * a * b * c, rel=1e-14)
    np.testing.assert_array_equal(centroid, 0.0)
    expected = np.diag([b * b + c * c, a * a + c * c, a * a + b * b]) * m / 12
    np.testing.assert_allclose(inertia, expected, rtol=1e-14)
    m2, _, polar = Box([a / 2, b / 2]).mass_properties(rho)
    assert m2 == pytest.approx(rho * a * b, rel=1e-14)
    assert polar == pytest.approx(m2 * (a * a + b * b) / 12, rel=1e-14)


def test_polygon_triangle_hand_values():
    # right triangle with unit legs: area 1/2, centroid (1/3, 1/3),
    # I_x = I_y = 1/36 about the centroid, so the polar moment is 1/18 per unit density
    tri = ConvexPolygon([[0.0, 1.0], [0.0, 0.0], [1.0, 0.0]])
    m, c, polar = tri.mass_properties(3.0)
    assert m == pytest.approx(1.5, rel=1e-14)
    np.testing.assert_allclose(c, [1 / 3, 1 / 3], rtol=1e-14)
    assert polar == pytest.approx(3.0 / 18.0, rel=1e-14)


@pytest.mark.parametrize("n", [3, 5, 8, 64])
def test_regular_polygon(n):
    r, rho = 0.3, 1200.0
    poly = ConvexPolygon.regular(n, r)
    area = 0.5 * n * r * r * np.sin(2 * np.pi / n)
    m, c, polar = poly.mass_properties(rho)
    assert poly.volume() == pytest.approx(area, rel=1e-13)
    np.testing.assert_allclose(c, 0.0, atol=1e-15)
    expected = m * r * r / 6 * (1 + 2 * np.cos(np.pi / n) ** 2)
    assert polar == pytest.approx(expected, rel=1e-13)
    assert poly.bounding_radius == pytest.approx(r, rel=1e-14)


def test_cube_and_corner_tetrahedron_hand_values():
    a, rho = 0.2, 7800.0
    corners = np.array([[x, y, z] for x in (0, a) for y in (0, a) for z in (0, a)])
    cube = ConvexPolyhedron.from_vertices(corners)
    m, c, inertia = cube.mass_properties(rho)
    assert (len(cube.normals), len(cube.triangles)) == (6, 12)
    assert m == pytest.approx(rho * a**3, rel=1e-13)
    np.testing.assert_allclose(c, a / 2, rtol=1e-13)
    np.testing.assert_allclose(inertia, np.eye(3) * m * a * a / 6, rtol=1e-12,
                               atol=1e-15 * m * a * a)
    # tetrahedron (0, a e1, a e2, a e3): V = a^3/6, centroid a/4,
    # I_xx = 3 m a^2 / 40, I_xy = + m a^2 / 80 (products enter with a minus sign)
    tet = ConvexPolyhedron.from_vertices(np.vstack([np.zeros(3), a * np.eye(3)]))
    m, c, inertia = tet.mass_properties(rho)
    assert m == pytest.approx(rho * a**3 / 6, rel=1e-13)
    np.testing.assert_allclose(c, a / 4, rtol=1e-13)
    expected = m * a * a * (np.full((3, 3), 1 / 80) + np.eye(3) * (3 / 40 - 1 / 80))
    np.testing.assert_allclose(inertia, expected, rtol=1e-12)


def test_extruded_polygon_is_the_2d_polygon_times_height():
    poly, height, rho = ConvexPolygon.regular(6, 0.5), 0.3, 2000.0
    m2, _, polar = poly.mass_properties(rho)
    prism = ConvexPolyhedron.extrude(poly, height)
    m, c, inertia = prism.mass_properties(rho)
    assert m == pytest.approx(m2 * height, rel=1e-13)
    np.testing.assert_allclose(c, 0.0, atol=1e-15)
    side = 0.5 * polar * height + m * height**2 / 12  # regular n-gon: I_x = I_y = J / 2
    np.testing.assert_allclose(inertia, np.diag([side, side, polar * height]),
                               rtol=1e-12, atol=1e-14 * m)
    assert ConvexPolyhedron.from_faces(prism.normals, prism.offsets).volume() == \
        pytest.approx(prism.volume(), rel=1e-12)


@pytest.mark.parametrize("dim", [2, 3])
def test_mass_properties_against_monte_carlo(dim):
    """Random hull; 4e5 samples (seeded): relative tolerance 1e-2 of each size scale."""
    rng = np.random.default_rng(6)
    shape = random_polygon(rng) if dim == 2 else random_polyhedron(rng)
    lo, hi = shape.vertices.min(axis=0), shape.vertices.max(axis=0)
    x = rng.uniform(lo, hi, size=(400_000, dim))
    x = x[Delaunay(shape.vertices).find_simplex(x) >= 0]
    box_volume = np.prod(hi - lo)
    volume = box_volume * len(x) / 400_000
    c = x.mean(axis=0)
    r = x - c
    central = volume * (r.T @ r) / len(x)
    m, centroid, inertia = shape.mass_properties(1.0)
    size = shape.bounding_radius
    assert m == pytest.approx(volume, rel=1e-2)
    np.testing.assert_allclose(centroid, c, atol=1e-2 * size)
    polar = np.trace(central)
    expected = polar if dim == 2 else polar * np.eye(3) - central
    np.testing.assert_allclose(inertia, expected, atol=1e-2 * np.abs(expected).max())


# --- principal frames -------------------------------------------------------------


def test_principal_of_rotated_shifted_box_recovers_the_box():
    box, rho, shift = Box([1.0, 0.5, 0.25]), 2500.0, np.array([3.0, -4.0, 50.0])
    rot_true = Rotation.random(random_state=7).as_matrix()
    corners = box.corners() @ rot_true.T + shift
    shape, rot, c = ConvexPolyhedron.from_vertices(corners).principal(rho)
    np.testing.assert_allclose(shape.principal_moments(rho), np.sort(
        box.principal_moments(rho)), rtol=1e-12)
    np.testing.assert_allclose(np.diag(shape.inertia_tensor(rho)),
                               box.principal_moments(rho), rtol=1e-12)  # x, y, z order
    np.testing.assert_allclose(c, shift, atol=1e-12 * 50)
    assert np.linalg.det(rot) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(rot.T @ rot, np.eye(3), atol=1e-12)
    # rot @ x + c maps the body frame back onto the given corners (same point set)
    back = shape.vertices @ rot.T + c
    assert cKDTree(corners).query(back)[0].max() < 1e-10
    # the body-frame shape is the box up to the sign of each axis
    assert np.abs(np.abs(shape.vertices) - box.half_extents).max() < 1e-12
    shape.rows()  # principal: accepted
    with pytest.raises(ValueError, match="offset"):
        ConvexPolyhedron.from_vertices(corners).rows()


def test_mass_properties_keep_precision_far_from_the_origin():
    rng = np.random.default_rng(11)
    for dim in (2, 3):
        points = rng.normal(size=(20, dim)) * 1e-3  # a 1 mm grain ...
        make = ConvexPolygon if dim == 2 else ConvexPolyhedron.from_vertices
        near, far = make(points), make(points + 1e3)  # ... and the same 1 km away
        m0, c0, i0 = near.mass_properties(2500.0)
        m1, c1, i1 = far.mass_properties(2500.0)
        assert m1 == pytest.approx(m0, rel=1e-9)
        np.testing.assert_allclose(c1 - 1e3, c0, atol=1e-12)
        np.testing.assert_allclose(i1, i0, rtol=1e-8, atol=1e-9 * np.abs(i0).max())
        far.principal(2500.0)[0].rows()


def test_principal_moments_follow_the_axes_of_a_principal_frame():
    box, rho = Box([0.25, 0.5, 1.0]), 100.0  # moments descending along x, y, z
    poly = ConvexPolyhedron.from_vertices(box.corners())
    np.testing.assert_allclose(poly.principal_moments(rho), box.principal_moments(rho),
                               rtol=1e-12)
    shape, rot, _ = poly.principal(rho)  # re-ordered ascending, and consistent
    np.testing.assert_allclose(shape.principal_moments(rho),
                               np.sort(box.principal_moments(rho)), rtol=1e-12)
    np.testing.assert_allclose(np.abs(rot), np.eye(3)[::-1], atol=1e-12)


def test_principal_of_polygon_recentres_only():
    poly = random_polygon(np.random.default_rng(8))
    shape, rot, c = poly.principal(1000.0)
    np.testing.assert_array_equal(rot, np.eye(2))
    np.testing.assert_allclose(shape.vertices + c, poly.vertices, atol=1e-14)
    np.testing.assert_allclose(shape.centroid(), 0.0, atol=1e-15)
    assert shape.inertia_tensor(1000.0) == pytest.approx(poly.inertia_tensor(1000.0),
                                                         rel=1e-12)
    assert shape.principal_moments(1000.0).shape == (1,)
    with pytest.raises(ValueError, match="offset"):
        poly.rows()


def test_box_principal_is_itself():
    box = Box([0.3, 0.2])
    shape, rot, c = box.principal(10.0)
    assert shape is box and (rot == np.eye(2)).all() and (c == 0).all()


@pytest.mark.parametrize("s", [0.5, 3.0])
def test_scaled_shapes(s):
    rng = np.random.default_rng(9)
    for shape in (Box([0.3, 0.2, 0.1]), random_polygon(rng), random_polyhedron(rng)):
        big = shape.scaled(s)
        x = sample_points(rng, shape, 200)
        np.testing.assert_allclose(big.sdf(s * x), s * shape.sdf(x), atol=1e-12)
        assert big.volume() == pytest.approx(shape.volume() * s**shape.dim, rel=1e-12)
        assert big.bounding_radius == pytest.approx(s * shape.bounding_radius,
                                                    rel=1e-14)


# --- custom shapes: numerical mass properties ---------------------------------------


def test_custom_sphere_error_and_time_at_default_resolution():
    """Stated error: below 2e-4 for spheres, bounding radius 1 - 2 x the radius."""
    radius = 0.01
    for dim, bound in ((3, 1.0), (3, 1.7), (2, 1.0), (2, 1.7)):
        shape = CustomShape(sdf_sphere_user, bound * radius, dim, params=[radius])
        shape.scaled(1.0).volume()  # compile
        start = time.perf_counter()
        m, c, inertia = shape.mass_properties(1.0)
        elapsed = time.perf_counter() - start
        if dim == 3:
            exact_m = 4 / 3 * np.pi * radius**3
            moments, exact_i = np.diag(inertia), 0.4 * exact_m * radius**2
        else:
            exact_m = np.pi * radius**2
            moments, exact_i = np.array([inertia]), 0.5 * exact_m * radius**2
        assert abs(m / exact_m - 1) < 2e-4
        assert np.abs(moments / exact_i - 1).max() < 2e-4
        assert np.abs(c).max() < 1e-12 * radius
        assert elapsed < 1.0  # about 0.1 s unloaded


@pytest.mark.parametrize("exponent", [2.0, 6.0])
def test_custom_superellipsoid_within_stated_error(exponent):
    """Semi-axes (1, 0.7, 0.4) m: volume and moments within 1e-3 at the default grid."""
    a, b, c, e = 1.0, 0.7, 0.4, exponent
    g = math.gamma
    volume = 8 * a * b * c * g(1 / e) ** 3 / (e**3 * g(1 + 3 / e))
    x2 = 8 * g(3 / e) * g(1 / e) ** 2 / (e**3 * g(1 + 5 / e))  # int x^2, unit ball
    sxx, syy, szz = x2 * a**3 * b * c, x2 * a * b**3 * c, x2 * a * b * c**3
    shape = CustomShape(sdf_superellipsoid, math.sqrt(a * a + b * b + c * c), 3,
                        params=[a, b, c, e])
    m, _, inertia = shape.mass_properties(1.0)
    assert m == pytest.approx(volume, rel=1e-3)
    np.testing.assert_allclose(np.diag(inertia), [syy + szz, sxx + szz, sxx + syy],
                               rtol=1e-3)
    assert np.abs(inertia - np.diag(np.diag(inertia))).max() < 1e-12


def test_custom_principal_finds_the_box_frame():
    rho, box = 1000.0, Box([1.0, 0.5, 0.25])
    p = [0.4, 0.7, 0.2, -0.1]
    shape = CustomShape(sdf_rotated_box, 1.35, 3, params=p)
    body, rot, c = shape.principal(rho)
    np.testing.assert_allclose(c, [0.2, -0.1, 0.0], atol=1e-5)
    np.testing.assert_allclose(body.principal_moments(rho), box.principal_moments(rho),
                               rtol=1e-3)
    rz = Rotation.from_rotvec([0, 0, p[0]]).as_matrix()
    rx = Rotation.from_rotvec([p[1], 0, 0]).as_matrix()
    np.testing.assert_allclose(np.abs(rot), np.abs(rx @ rz), atol=1e-3)  # up to signs
    assert np.linalg.det(rot) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(body.rotation, rot, atol=1e-15)
    np.testing.assert_allclose(body.offset, c, atol=1e-15)
    m, centroid, inertia = body.mass_properties(rho)
    assert np.abs(centroid).max() == 0.0 and np.count_nonzero(inertia - np.diag(
        np.diag(inertia))) == 0
    assert body.bounding_radius == pytest.approx(1.35 + np.linalg.norm(c))
    # recomputing on the moved grid agrees within the stated error
    fresh = CustomShape(sdf_rotated_box, body.bounding_radius, 3, params=p)
    fresh.rotation, fresh.offset = body.rotation, body.offset
    m2, centroid2, inertia2 = fresh.mass_properties(rho)
    assert m2 == pytest.approx(m, rel=1e-3)
    assert np.abs(centroid2).max() < 1e-3
    np.testing.assert_allclose(inertia2, inertia, atol=1e-3 * np.abs(inertia).max())


def test_custom_2d_principal_recentres():
    shape = CustomShape(sdf_sphere_user, 1.0, 2, params=[0.4, 0.3, -0.2])
    body, rot, c = shape.principal(1.0)
    np.testing.assert_array_equal(rot, np.eye(2))
    np.testing.assert_allclose(c, [0.3, -0.2], atol=1e-6)
    np.testing.assert_allclose(body.offset, [*c, 0.0])
    assert body.sdf([0.0, 0.0]) == pytest.approx(-0.4, abs=1e-5)
    assert body.principal_moments(1.0).shape == (1,)


# --- rows ---------------------------------------------------------------------------


def all_principal_shapes():
    rng = np.random.default_rng(10)
    return [Box([0.3, 0.2]), Box([0.3, 0.2, 0.1]), random_polygon(rng).principal()[0],
            random_polyhedron(rng).principal()[0],
            ConvexPolyhedron.extrude(ConvexPolygon.regular(5, 0.2), 0.1).principal()[0]]


@pytest.mark.parametrize("shape", all_principal_shapes(), ids=repr)
def test_rows_layout(shape):
    row = shape.rows()
    verts, faces, tris = row["verts"], row["faces"], row["tris"]
    assert row["kind"] == shape.code
    assert row["param"].shape == (4,) and row["param"].dtype == np.float64
    assert verts.dtype == faces.dtype == np.float64 and tris.dtype == np.int64
    assert verts.shape[1] == 3 and faces.shape[1] == 4 and tris.shape[1] == 3
    assert row["bounding_radius"] == pytest.approx(np.linalg.norm(verts, axis=1).max())
    n, o = faces[:, :3], faces[:, 3]
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, rtol=1e-14)
    assert (o >= 0).all()  # the origin (centroid) is inside
    assert (verts @ n.T <= o + 1e-12).all()
    for f in range(len(faces)):  # every face touches at least two vertices
        assert np.sum(np.abs(verts @ n[f] - o[f]) < 1e-12) >= 2
    if shape.dim == 2:
        assert len(tris) == 0 and (verts[:, 2] == 0).all() and (n[:, 2] == 0).all()
        k = len(verts)
        for e in range(k):  # edge e joins verts[e] -> verts[e+1] and lies on face e
            a, b = verts[e], verts[(e + 1) % k]
            assert abs(a @ n[e] - o[e]) < 1e-12 and abs(b @ n[e] - o[e]) < 1e-12
            assert np.cross(b - a, n[e])[2] < 0  # CCW: outward normal on the right
        area = 0.5 * np.sum(np.cross(verts, np.roll(verts, -1, axis=0))[:, 2])
        assert area == pytest.approx(shape.volume(), rel=1e-12)
    else:
        a, b, c = verts[tris[:, 0]], verts[tris[:, 1]], verts[tris[:, 2]]
        signed = np.einsum("ij,ij->i", a, np.cross(b, c)) / 6
        assert (signed > 0).all()  # outward, seen from the interior origin
        assert signed.sum() == pytest.approx(shape.volume(), rel=1e-12)
        assert np.unique(tris).size == len(verts)
        normal = np.cross(b - a, c - a)
        normal /= np.linalg.norm(normal, axis=1)[:, None]
        assert (np.abs(normal @ n.T - 1.0).min(axis=1) < 1e-12).all()  # on some face


def test_rows_of_box_match_its_polygon_and_polyhedron():
    box2 = Box([0.3, 0.2])
    poly = ConvexPolygon(box2.corners())
    r_box, r_poly = box2.rows(), poly.rows()
    np.testing.assert_array_equal(r_box["param"], [0.3, 0.2, 0.0, 0.0])
    # same ring of corners (up to the starting vertex) and the same half-planes
    shift = int(np.flatnonzero((np.abs(r_poly["verts"] - r_box["verts"][0]) < 1e-15)
                               .all(axis=1))[0])
    np.testing.assert_allclose(np.roll(r_poly["verts"], -shift, axis=0), r_box["verts"])
    np.testing.assert_allclose(np.roll(r_poly["faces"], -shift, axis=0), r_box["faces"],
                               atol=1e-15)
    box3 = Box([0.3, 0.2, 0.1])
    r3 = box3.rows()
    np.testing.assert_array_equal(r3["param"], [0.3, 0.2, 0.1, 0.0])
    assert r3["verts"].shape == (8, 3) and r3["faces"].shape == (6, 4)
    assert r3["tris"].shape == (12, 3)
    p3 = ConvexPolyhedron.from_vertices(box3.corners()).rows()  # same half-spaces

    def by_rows(a):
        return a[np.lexsort(a.T[::-1])]

    np.testing.assert_allclose(by_rows(np.round(p3["faces"], 12)),
                               by_rows(r3["faces"]), atol=1e-12)


def test_custom_rows():
    shape = CustomShape(sdf_sphere_user, 1.0, 3, params=[0.5, 0.1])
    row = shape.rows()
    assert row["kind"] == 5 and row["bounding_radius"] == 1.0
    np.testing.assert_array_equal(row["param"], [0.5, 0.1, 0.0, 0.0])
    assert row["verts"].shape == (0, 3) and row["faces"].shape == (0, 4)
    assert row["tris"].shape == (0, 3) and row["tris"].dtype == np.int64
    np.testing.assert_array_equal(shape.offset, 0.0)
    np.testing.assert_array_equal(shape.rotation, np.eye(3))


# --- errors ---------------------------------------------------------------------------


@pytest.mark.parametrize("h, match", [
    ([1.0, np.nan, 1.0], "finite"), ([1.0, np.inf], "finite"), ([1.0, -0.5], "> 0"),
    ([1.0, 0.0, 1.0], "> 0"), ([1.0], "2 or 3"), ([1.0] * 4, "2 or 3")])
def test_box_errors(h, match):
    with pytest.raises(ValueError, match=match):
        Box(h)


@pytest.mark.parametrize("v, match", [
    ([[0, 0], [1, 1], [2, 2], [3, 3]], "collinear"), ([[0, 0], [1, 0]], "at least 3"),
    ([[0, 0], [1, 0], [np.nan, 1]], "finite"), ([[0, 0], [0, 0], [0, 0]], "collinear"),
    ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], "shape")])
def test_polygon_errors(v, match):
    with pytest.raises(ValueError, match=match):
        ConvexPolygon(v)


def test_regular_polygon_errors():
    with pytest.raises(ValueError, match="n >= 3"):
        ConvexPolygon.regular(2, 1.0)
    with pytest.raises(ValueError, match="circumradius"):
        ConvexPolygon.regular(5, -1.0)


@pytest.mark.parametrize("v, match", [
    (np.eye(3), "at least 4"),
    ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], "coplanar"),
    (np.vstack([np.eye(3), [[np.inf, 0, 0]]]), "finite"), (np.zeros((5, 2)), "shape")])
def test_polyhedron_errors(v, match):
    with pytest.raises(ValueError, match=match):
        ConvexPolyhedron.from_vertices(v)


def test_from_faces_errors():
    n = np.vstack([np.eye(3), -np.eye(3)])
    with pytest.raises(ValueError, match="unbounded|no finite"):
        ConvexPolyhedron.from_faces(n[:5], np.ones(5))
    with pytest.raises(ValueError, match="empty or flat"):
        ConvexPolyhedron.from_faces(n, [1, 1, 1, -2, 1, 1])
    with pytest.raises(ValueError, match="empty or flat"):
        ConvexPolyhedron.from_faces(n, [1, 1, 0, 1, 1, 0])
    with pytest.raises(ValueError, match="non-zero"):
        ConvexPolyhedron.from_faces(np.vstack([n, np.zeros(3)]), np.ones(7))
    with pytest.raises(ValueError, match="height must be a positive"):
        ConvexPolyhedron.extrude(ConvexPolygon.regular(4, 1.0), -1.0)


def test_density_and_scale_errors():
    box = Box([1.0, 1.0])
    with pytest.raises(ValueError, match="density"):
        box.mass_properties(-1.0)
    with pytest.raises(ValueError, match="density"):
        random_polyhedron(np.random.default_rng(0)).mass_properties(np.nan)
    with pytest.raises(ValueError, match="scale"):
        box.scaled(0.0)


def test_custom_errors():
    with pytest.raises(TypeError, match="numba.njit"):
        CustomShape(lambda x, y, z, p: 0.0, 1.0, 3)
    with pytest.raises(ValueError, match="bounding_radius"):
        CustomShape(sdf_sphere_user, -1.0, 3)
    with pytest.raises(ValueError, match="dim"):
        CustomShape(sdf_sphere_user, 1.0, 4)
    with pytest.raises(ValueError, match="at most 4"):
        CustomShape(sdf_sphere_user, 1.0, 3, params=[1, 2, 3, 4, 5])
    with pytest.raises(ValueError, match="resolution"):
        CustomShape(sdf_sphere_user, 1.0, 3, resolution=4)
    with pytest.raises(ValueError, match="beyond its bounding_radius"):
        CustomShape(sdf_sphere_user, 0.9, 3, params=[1.0]).volume()
    with pytest.raises(ValueError, match="not negative anywhere"):
        CustomShape(sdf_sphere_user, 1.0, 2, params=[-1.0]).volume()
