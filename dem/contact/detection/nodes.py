"""The surface-node method of LS-DEM: the baseline of the speed-accuracy comparison.

LS-DEM (Kawamoto et al. 2016) represents body A by nodes on its surface and body B by
its signed distance function; every node of A with ``phi_B < 0`` penetrates B and
carries a force along ``-grad phi_B``. For the comparison with the optimisation-based
detection (:mod:`dem.contact.detection.admm`) this module reduces the penetrating nodes
to the contract's single summary (see :mod:`dem.contact.detection`): the deepest node
is P1's point ``x1``, ``ov = -phi_B(x1)``, ``n = -grad phi_B(x1)`` (central
differences), ``c = x1 - ov/2 n``. It is P1 restricted to the nodes: it only sees
A's points inside B (never B's corner in A's face, P2), and its depth is exact only
when a node sits at the deepest point; the cost grows with the node count (one SDF
evaluation per node) and so does the accuracy.
"""

import math

import numpy as np

from ..._jit import kernel
from ...rotation import to_body, to_world
from ...shapes.kinds import BOX, CUSTOM, PLANE, POLYGON
from ...shapes.table import GRAD_STEP, sdf_local
from .admm import _sdf


# --------------------------------------------------------------------------- nodes
def _fibonacci_sphere(n):
    """``n`` unit vectors spread evenly over the sphere (golden-angle spiral)."""
    i = np.arange(n) + 0.5
    zc = 1.0 - 2.0 * i / n
    r = np.sqrt(1.0 - zc * zc)
    phi = np.pi * (3.0 - np.sqrt(5.0)) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), zc], axis=1)


def _ray_surface(sdf, directions, radius, n_bisect=60):
    """Points where rays from the origin along ``directions`` (m, d) leave the shape.

    Bisection on ``sdf(r d) = 0`` for ``r`` in ``[0, 1.01 radius]``: the shape must
    contain the origin and be star-shaped about it (every convex body in its frame).
    """
    lo = np.zeros(len(directions))
    hi = np.full(len(directions), 1.01 * radius)
    for _ in range(n_bisect):
        mid = 0.5 * (lo + hi)
        inside = sdf(mid[:, None] * directions) < 0.0
        lo = np.where(inside, mid, lo)
        hi = np.where(inside, hi, mid)
    return 0.5 * (lo + hi)[:, None] * directions


def _resample_closed(points, n_nodes):
    """``n_nodes`` points evenly spaced by arc length along a closed polyline (k, 2)."""
    closed = np.vstack([points, points[:1]])
    seg = np.linalg.norm(np.diff(closed, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    target = np.arange(n_nodes) * s[-1] / n_nodes
    out = np.empty((n_nodes, 2))
    for a in range(2):
        out[:, a] = np.interp(target, s, closed[:, a])
    return out


def _triangle_nodes(verts, tris, n_nodes):
    """About ``n_nodes`` points evenly spread over a triangulated surface: each triangle
    gets a share by area, filled with the R2 low-discrepancy sequence (folded into it)."""
    a, b, c = verts[tris[:, 0]], verts[tris[:, 1]], verts[tris[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    share = area * n_nodes / area.sum()
    count = np.floor(share).astype(np.int64)
    rest = n_nodes - count.sum()  # largest remainders get one more
    count[np.argsort(share - count)[::-1][:rest]] += 1
    g = 1.32471795724474602596  # plastic number: the R2 sequence
    out = []
    for t in np.flatnonzero(count):
        i = np.arange(1, count[t] + 1)
        u, v = (0.5 + i / g) % 1.0, (0.5 + i / g**2) % 1.0
        flip = u + v > 1.0
        u[flip], v[flip] = 1.0 - u[flip], 1.0 - v[flip]
        out.append(a[t] + u[:, None] * (b[t] - a[t]) + v[:, None] * (c[t] - a[t]))
    return np.vstack(out)


def _polygon_vertices(shape):
    """The (k, 2) counter-clockwise vertices of a polygon-like shape, or None."""
    if isinstance(shape, dict):
        polygon = int(shape.get("kind", -1)) in (BOX, POLYGON)
        if polygon and len(shape.get("verts", [])) >= 3:
            return np.asarray(shape["verts"], dtype=np.float64)[:, :2]
        return None
    v = getattr(shape, "vertices", None)
    if v is not None and np.ndim(v) == 2 and np.shape(v)[1] == 2:
        return np.asarray(v, dtype=np.float64)
    return None


def surface_nodes(shape, n_nodes, dim, radius=None):
    """Body-frame points on the zero level set of a shape, roughly evenly spread.

    Parameters
    ----------
    shape : callable, shape object or table rows (dict)
        ``sdf(points (m, dim)) -> (m,)`` [m]; or an object with such an ``sdf`` method
        (and a ``bounding_radius``); or a shape's ``rows()`` dict. For a polygon (an
        object with ``vertices`` (k, 2), or BOX / POLYGON rows) the 2D nodes are spaced
        evenly by arc length along its edges (its vertices need not be nodes); rows
        with boundary triangles (a 3D box, a polyhedron) spread them over the triangles
        by area.
    n_nodes : int
        Number of nodes, >= 3 (2D) or >= 4 (3D).
    dim : int
        2 or 3.
    radius : float, optional
        Bounding radius [m]; read from the shape if omitted.

    Returns
    -------
    ndarray, shape (n_nodes, dim), float64
        Nodes [m] in the body frame. In 2D, by arc length; in 3D from an SDF, the rays
        of a Fibonacci sphere from the origin cut with the surface by bisection (even
        in solid angle, so denser where the surface is nearer the centre), which needs
        a shape star-shaped about its centre.

    Examples
    --------
    >>> sdf = lambda x: np.linalg.norm(x, axis=1) - 2.0
    >>> nodes = surface_nodes(sdf, 8, 2, radius=2.0)
    >>> nodes.shape, bool(np.allclose(np.linalg.norm(nodes, axis=1), 2.0))
    ((8, 2), True)
    """
    if dim not in (2, 3):
        raise ValueError(f"dim must be 2 or 3, got {dim}")
    n_nodes = int(n_nodes)
    if n_nodes < dim + 1:
        raise ValueError(f"need at least {dim + 1} nodes, got {n_nodes}")
    verts = _polygon_vertices(shape) if dim == 2 else None
    if verts is not None:
        return _resample_closed(verts, n_nodes)
    if isinstance(shape, dict):
        tris = np.asarray(shape.get("tris", np.zeros((0, 3))), dtype=np.int64)
        tris = tris.reshape(-1, 3)
        if dim == 3 and len(tris) > 0:
            return _triangle_nodes(np.asarray(shape["verts"], dtype=np.float64), tris,
                                   n_nodes)
        raise ValueError("table rows give nodes only for polygons, boxes and polyhedra; "
                         "pass an SDF function for other shapes")
    sdf = shape if callable(shape) and not hasattr(shape, "sdf") else shape.sdf
    if radius is None:
        radius = getattr(shape, "bounding_radius", None)
        if radius is None:
            raise ValueError("radius is needed for a bare SDF function")
    radius = float(radius)
    if dim == 3:
        return _ray_surface(sdf, _fibonacci_sphere(n_nodes), radius)
    ang = 2.0 * np.pi * np.arange(64 * n_nodes) / (64 * n_nodes)  # a fine boundary,
    fine = _ray_surface(sdf, np.stack([np.cos(ang), np.sin(ang)], axis=1), radius)
    return _resample_closed(fine, n_nodes)  # then even arc length


def nodes_as3(nodes):
    """Nodes (m, 2) or (m, 3) as the (m, 3) C-contiguous float64 array the kernel takes."""
    nodes = np.asarray(nodes, dtype=np.float64)
    out = np.zeros((nodes.shape[0], 3))
    out[:, :nodes.shape[1]] = nodes
    return out


# --------------------------------------------------------------------------- contact
@kernel
def nodes_contact(dim, a, nodes_a, kb, sb, b, sx, sy, sz, pos, rot, normal, geo):
    """Contact summary of body ``a`` (surface nodes) against body ``b`` (its SDF).

    Parameters
    ----------
    dim : int
        2 or 3.
    a : int
        Body index of A, whose surface is ``nodes_a``.
    nodes_a : (m, 3) float64
        A's nodes [m] in A's body frame (``z = 0`` in 2D; see :func:`nodes_as3`).
    kb, sb, b : int
        Kind (SPHERE, BOX, POLYGON, POLYHEDRON rows or PLANE; CUSTOM through
        :func:`nodes_contact_fn`), shape-table row and body index of B.
    sx, sy, sz : float
        Periodic shift [m] added to ``b``'s position.
    pos, rot, normal, geo
        As :func:`dem.contact.detection.admm.admm_contact`.

    Returns
    -------
    ov, nx, ny, nz, cx, cy, cz : float
        The contract's summary from the deepest node (``ov <= 0``: no node inside B,
        ``-ov`` is the smallest node clearance).
    iters : int
        0 (not iterative).
    """
    return _nodes(np.int64(0), dim, a, nodes_a, kb, sb, b, sx, sy, sz, pos, rot, normal,
                  geo)


@kernel
def nodes_contact_fn(fn, dim, a, nodes_a, kb, sb, b, sx, sy, sz, pos, rot, normal, geo):
    """:func:`nodes_contact` with CUSTOM rows evaluated by the C function at address
    ``fn`` (:func:`dem.contact.detection.admm.custom_address`)."""
    return _nodes(fn, dim, a, nodes_a, kb, sb, b, sx, sy, sz, pos, rot, normal, geo)


@kernel(inline=True)
def _nodes(fn, dim, a, nodes_a, kb, sb, b, sx, sy, sz, pos, rot, normal, geo):
    """:func:`nodes_contact` with ``fn`` the custom SDF's address (0: none)."""
    obx = pos[b, 0] + sx - pos[a, 0]  # B's centre relative to A's
    oby = pos[b, 1] + sy - pos[a, 1]
    obz = pos[b, 2] + sz - pos[a, 2] if dim == 3 else 0.0
    h = GRAD_STEP * geo[8][sb] * geo[1][sb] if kb != PLANE else 1.0
    bd = (np.int64(kb), np.int64(sb), np.int64(b), obx, oby, obz, h)
    best, bx, by, bz = math.inf, 0.0, 0.0, 0.0
    for i in range(nodes_a.shape[0]):
        x, y, z = to_world(dim, rot, a, nodes_a[i, 0], nodes_a[i, 1], nodes_a[i, 2])
        if kb == PLANE:
            d = normal[b, 0] * (x - obx) + normal[b, 1] * (y - oby)
            if dim == 3:
                d += normal[b, 2] * (z - obz)
        elif kb == CUSTOM:
            d = _sdf(fn, dim, bd, x, y, z, rot, normal, geo, np.int64(0))[0]
        else:
            lx, ly, lz = to_body(dim, rot, b, x - obx, y - oby, z - obz)
            d = sdf_local(kb, sb, lx, ly, lz, geo)
        if d < best:
            best, bx, by, bz = d, x, y, z
    _, gx, gy, gz = _sdf(fn, dim, bd, bx, by, bz, rot, normal, geo, np.int64(1))
    gn = math.sqrt(gx * gx + gy * gy + gz * gz)
    if gn > 0.0:
        gx, gy, gz = gx / gn, gy / gn, gz / gn
    ov = -best
    nx, ny, nz = -gx, -gy, -gz
    cx = bx - 0.5 * ov * nx + pos[a, 0]
    cy = by - 0.5 * ov * ny + pos[a, 1]
    cz = bz - 0.5 * ov * nz + pos[a, 2] if dim == 3 else 0.0
    if dim == 2:
        nz = 0.0
    return ov, nx, ny, nz, cx, cy, cz, 0
