"""The contact of a polytope with a wall (a plane body)."""

import math

from ...._jit import kernel
from ....rotation import to_body, to_world


@kernel(inline=True)
def polytope_plane(dim, sa, a, w, pos, rot, normal, geo):
    """Contact of polytope body ``a`` (shape row ``sa``) with the wall body ``w``.

    The wall passes through ``pos[w]`` with unit free-side normal ``normal[w]``; its
    solid lies behind. The overlap is the depth of A's deepest vertex, ``ov = -min_v
    normal[w] . (v - pos[w])``, and the normal from A to the wall is ``-normal[w]``. The
    contact point lies ``ov / 2`` in front of the depth-weighted mean of the vertices
    behind the wall (weights: their depths): the deepest vertex alone when only one has
    gone through, the middle of a face lying flat. The point, and so the torque, moves
    continuously as a face tilts, where jumping from corner to corner would make a box
    resting flat chatter on the wall at the time step's scale. (A distributed support:
    with two or more vertices through, the force is not the gradient of a potential.)

    Returns ``(ov, nx, ny, nz, cx, cy, cz, 0)``; ``pos``, ``rot`` as in
    :func:`~dem.contact.detection.polytope.polytope_contact`, ``normal`` (n, dim)
    float64.
    """
    scale, vstart, verts = geo[1], geo[2], geo[3]
    sc = scale[sa]
    wx, wy = normal[w, 0], normal[w, 1]
    wz = normal[w, 2] if dim == 3 else 0.0
    mx, my, mz = to_body(dim, rot, a, wx, wy, wz)  # the wall normal in A's frame
    base = wx * (pos[a, 0] - pos[w, 0]) + wy * (pos[a, 1] - pos[w, 1])
    if dim == 3:
        base += wz * (pos[a, 2] - pos[w, 2])
    v0, v1 = vstart[sa], vstart[sa + 1]
    lo = math.inf
    for v in range(v0, v1):
        lo = min(lo, mx * verts[v, 0] + my * verts[v, 1] + mz * verts[v, 2])
    ov = -(base + sc * lo)
    if ov <= 0.0:
        return ov, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0
    ax, ay, az, wsum = 0.0, 0.0, 0.0, 0.0
    for v in range(v0, v1):
        depth = -(base + sc * (mx * verts[v, 0] + my * verts[v, 1] + mz * verts[v, 2]))
        if depth > 0.0:
            ax += depth * verts[v, 0]
            ay += depth * verts[v, 1]
            az += depth * verts[v, 2]
            wsum += depth
    k = sc / wsum
    xx, xy, xz = to_world(dim, rot, a, k * ax, k * ay, k * az)
    # the weighted point lies at depth sum(d^2)/sum(d) <= ov: put c at ov/2 in front
    # of the deepest level, on the line through the weighted point along the normal
    dw = -(base + wx * xx + wy * xy + wz * xz)
    h = dw - 0.5 * ov
    cx = pos[a, 0] + xx + h * wx
    cy = pos[a, 1] + xy + h * wy
    cz = pos[a, 2] + xz + h * wz if dim == 3 else 0.0
    return ov, -wx, -wy, -wz, cx, cy, cz, 0
