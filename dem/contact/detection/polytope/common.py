"""Tolerances and small helpers shared by the 2D and 3D polytope kernels."""

from ...._jit import kernel
from ....rotation import to_world

#: relative tolerance of ties (equal depths, equally deep faces or vertices)
TIE = 1e-12
#: a pivot row must cross the edge direction by more than this (relative to |d|)
_CROSS = 1e-12
_MAX_PIVOTS = 100
#: width of the smooth maximum of two bodies' corner depths, relative to their mean
BLEND = 0.25


@kernel(inline=True)
def better_ratio(r, gd, k, rmin, kin, gbest, bland, tol):
    """The simplex ratio test's choice between the best row so far ``(rmin, kin,
    gbest)`` and row ``k`` of step ``r`` and slope ``gd``: the smaller step, and among
    steps equal to ``tol`` the steeper row (Harris), unless Bland's rule is on (the
    first row kept). Returns the new ``(rmin, kin, gbest)``."""
    if r < rmin - tol:
        return r, k, gd
    if r <= rmin + tol and not bland and gd > gbest:
        return min(r, rmin), k, gd
    return rmin, kin, gbest


@kernel(inline=True)
def cross3(ax, ay, az, bx, by, bz):
    """The cross product ``a x b``."""
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


#: the pose of a body in its own frame: ``R = I``, ``p = 0``
IDENTITY3 = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)


@kernel(inline=True)
def turn3(pose, x, y, z):
    """``R x`` for a pose ``(R row-major, p)``, a body placed at ``R x + p``."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22, _, _, _ = pose
    return (r00 * x + r01 * y + r02 * z, r10 * x + r11 * y + r12 * z,
            r20 * x + r21 * y + r22 * z)


@kernel(inline=True)
def place3(pose, x, y, z):
    """``R x + p``: a point of the placed body in the outer frame."""
    ax, ay, az = turn3(pose, x, y, z)
    return ax + pose[9], ay + pose[10], az + pose[11]


@kernel(inline=True)
def unturn3(pose, x, y, z):
    """``R^T x``: a direction of the outer frame in the placed body's."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22, _, _, _ = pose
    return (r00 * x + r10 * y + r20 * z, r01 * x + r11 * y + r21 * z,
            r02 * x + r12 * y + r22 * z)


@kernel(inline=True)
def face_row3(g, sc, pose, faces):
    """Face ``g`` of a body placed at ``R x + p`` (scale ``sc``): (normal, offset)."""
    ax, ay, az = turn3(pose, faces[g, 0], faces[g, 1], faces[g, 2])
    return ax, ay, az, sc * faces[g, 3] + ax * pose[9] + ay * pose[10] + az * pose[11]


@kernel(inline=True)
def _matrix3(rot, b):
    """Body ``b``'s rotation matrix (body to world), row-major, from its quaternion."""
    r00, r10, r20 = to_world(3, rot, b, 1.0, 0.0, 0.0)
    r01, r11, r21 = to_world(3, rot, b, 0.0, 1.0, 0.0)
    r02, r12, r22 = to_world(3, rot, b, 0.0, 0.0, 1.0)
    return r00, r01, r02, r10, r11, r12, r20, r21, r22


@kernel(inline=True)
def _cross4(a0, a1, a2, a3, b0, b1, b2, b3, c0, c1, c2, c3):
    """The vector ``e`` with ``e . u = det[u; a; b; c]``: orthogonal to a, b and c."""
    m01 = b0 * c1 - b1 * c0
    m02 = b0 * c2 - b2 * c0
    m03 = b0 * c3 - b3 * c0
    m12 = b1 * c2 - b2 * c1
    m13 = b1 * c3 - b3 * c1
    m23 = b2 * c3 - b3 * c2
    return (a1 * m23 - a2 * m13 + a3 * m12, -(a0 * m23 - a2 * m03 + a3 * m02),
            a0 * m13 - a1 * m03 + a3 * m01, -(a0 * m12 - a1 * m02 + a2 * m01))


@kernel(inline=True)
def smooth_max(d1, d2):
    """``(S, dS/dd1, dS/dd2)``: a C1 maximum of two depths.

    ``S = max`` where ``|d1 - d2| >= h``, ``h = BLEND (d1 + d2) / 2``; within, the
    quadratic blend ``m + h / 4 + (d1 - d2)^2 / (4 h)`` (``m`` the mean), at most
    ``BLEND / 4`` of the depth above the maximum (at a tie, where the gradient's
    components sum to ``1 + BLEND / 4``). Homogeneous of degree one, so it is a
    function of the depths alone and its gradient a force field.
    """
    m = 0.5 * (d1 + d2)
    h = BLEND * m
    x = d1 - d2
    if h <= 0.0 or x >= h:
        return d1, 1.0, 0.0
    if -x >= h:
        return d2, 0.0, 1.0
    q = BLEND * x * x / (8.0 * h * h)
    return (m + 0.25 * h + x * x / (4.0 * h), 0.5 + BLEND / 8.0 + x / (2.0 * h) - q,
            0.5 + BLEND / 8.0 - x / (2.0 * h) - q)


@kernel(inline=True)
def smooth_min(d1, d2):
    """``(S, dS/dd1, dS/dd2)``: the C1 minimum of two depths matching :func:`smooth_max`
    (``S = d1 + d2 - smooth_max``), the minimum itself, exactly, where they are further
    apart than ``h``."""
    h = BLEND * 0.5 * (d1 + d2)
    if h <= 0.0 or d2 - d1 >= h:
        return d1, 1.0, 0.0
    if d1 - d2 >= h:
        return d2, 0.0, 1.0
    s, w1, w2 = smooth_max(d1, d2)
    return d1 + d2 - s, 1.0 - w1, 1.0 - w2
