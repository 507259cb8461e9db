"""Orientations: quaternion and angle helpers, and their kernel twins.

A 3D body's orientation is a unit quaternion ``(w, x, y, z)``, body to world; a 2D
body's is one angle [rad] about z (``Bodies.rot`` holds (n, 4) or (n, 1)). The
functions here work on one quaternion (:func:`quat_mul`, :func:`quat_rotate`,
:func:`quat_to_matrix`, :func:`matrix_to_quat`), on the rows of ``Bodies.rot``
(:func:`rotation_matrices`, :func:`body_frame`, :func:`world_frame`), or inside compiled
loops on one body's row (:func:`to_world`, :func:`to_body`, inlined into their callers).

This module imports nothing of ``dem`` but the compile options (``dem._jit``), so the
shapes, the particle table and the kernels can all use it.

>>> q = np.array([np.cos(np.pi / 4), 0.0, 0.0, np.sin(np.pi / 4)])  # 90 deg about z
>>> np.round(quat_rotate(q, [1.0, 0.0, 0.0]), 12).tolist()
[0.0, 1.0, 0.0]
>>> np.allclose(matrix_to_quat(quat_to_matrix(q)), q)
True
"""

import math

import numpy as np

from ._jit import kernel

__all__ = ["body_frame", "matrix_to_quat", "quat_mul", "quat_rotate", "quat_to_matrix",
           "rotation_matrices", "to_body", "to_world", "world_frame"]


# ----------------------------------------------------------------------- one quaternion
def quat_mul(p, q):
    """Hamilton product of quaternions (w, x, y, z)."""
    w1, x1, y1, z1 = p
    w2, x2, y2, z2 = q
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                     w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                     w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def quat_rotate(q, v):
    """Rotate vector ``v`` (3,) by unit quaternion ``q``."""
    return quat_to_matrix(q) @ np.asarray(v, np.float64)


def quat_to_matrix(q):
    """Rotation matrix (3, 3) of a unit quaternion (w, x, y, z)."""
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def matrix_to_quat(r):
    """Unit quaternion (w, x, y, z) of a rotation matrix (3, 3), w >= 0."""
    r = np.asarray(r, np.float64)
    t = np.trace(r)
    if t > 0.0:
        s = 2.0 * np.sqrt(t + 1.0)
        q = np.array([0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s,
                      (r[1, 0] - r[0, 1]) / s])
    else:
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k])
        q = np.empty(4)
        q[0] = (r[k, j] - r[j, k]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (r[j, i] + r[i, j]) / s
        q[1 + k] = (r[k, i] + r[i, k]) / s
    q /= np.linalg.norm(q)
    return q if q[0] >= 0.0 else -q


# ------------------------------------------------------------------- rows of Bodies.rot
def rotation_matrices(rot):
    """Body-to-world rotation matrices of orientations ``rot``.

    Parameters
    ----------
    rot : ndarray, shape (n, 1) or (n, 4), float64
        Angles [rad] (2D) or unit quaternions (w, x, y, z) (3D), as in ``Bodies.rot``.

    Returns
    -------
    ndarray, shape (n, 3, 3), float64
        In 2D the rotation about z.

    Examples
    --------
    >>> r = rotation_matrices(np.array([[np.pi / 2]]))
    >>> np.round(r[0] @ [1.0, 0.0, 0.0], 12).tolist()
    [0.0, 1.0, 0.0]
    """
    rot = np.asarray(rot, dtype=np.float64)
    n = rot.shape[0]
    out = np.zeros((n, 3, 3))
    if rot.shape[1] == 1:
        c, s = np.cos(rot[:, 0]), np.sin(rot[:, 0])
        out[:, 0, 0], out[:, 0, 1] = c, -s
        out[:, 1, 0], out[:, 1, 1] = s, c
        out[:, 2, 2] = 1.0
        return out
    w, x, y, z = rot.T
    out[:, 0] = np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z),
                          2 * (x * z + w * y)], axis=1)
    out[:, 1] = np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z),
                          2 * (y * z - w * x)], axis=1)
    out[:, 2] = np.stack([2 * (x * z - w * y), 2 * (y * z + w * x),
                          1 - 2 * (x * x + y * y)], axis=1)
    return out


def _quat_apply(q, v, inverse):
    w, u = q[:, :1], q[:, 1:].copy()
    if inverse:
        u = -u
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def body_frame(rot, vec):
    """World vectors (n, 3) into the bodies' frames (3D quaternions); 2D: unchanged."""
    return vec if rot.shape[1] == 1 else _quat_apply(rot, vec, True)


def world_frame(rot, vec):
    """Body-frame vectors (n, 3) into the world frame; 2D: unchanged."""
    return vec if rot.shape[1] == 1 else _quat_apply(rot, vec, False)


# ------------------------------------------------------------------------------ kernels
@kernel(inline=True)
def _quat_rotate(w, qx, qy, qz, x, y, z):
    """Rotate (x, y, z) by the unit quaternion (w, q): v + 2w (q x v) + 2 q x (q x v)."""
    tx = 2.0 * (qy * z - qz * y)
    ty = 2.0 * (qz * x - qx * z)
    tz = 2.0 * (qx * y - qy * x)
    return (x + w * tx + (qy * tz - qz * ty), y + w * ty + (qz * tx - qx * tz),
            z + w * tz + (qx * ty - qy * tx))


@kernel(inline=True)
def to_world(dim, rot, b, x, y, z):
    """Rotate a body-frame vector of body ``b`` into the world frame (no translation)."""
    if dim == 2:
        c, s = math.cos(rot[b, 0]), math.sin(rot[b, 0])
        return c * x - s * y, s * x + c * y, 0.0
    return _quat_rotate(rot[b, 0], rot[b, 1], rot[b, 2], rot[b, 3], x, y, z)


@kernel(inline=True)
def to_body(dim, rot, b, x, y, z):
    """Rotate a world-frame vector into body ``b``'s frame (the inverse of :func:`to_world`)."""
    if dim == 2:
        c, s = math.cos(rot[b, 0]), math.sin(rot[b, 0])
        return c * x + s * y, -s * x + c * y, 0.0
    return _quat_rotate(rot[b, 0], -rot[b, 1], -rot[b, 2], -rot[b, 3], x, y, z)
