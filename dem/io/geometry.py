"""The geometry viewers draw besides the particles: 2D vectors padded to 3D, 2D angles
as quaternions, walls as finite patches and polytope shapes as world-frame triangle
surfaces (what :class:`dem.io.H5Writer` writes for ParaView and meshio)."""

import numpy as np

from ..rotation import rotation_matrices
from ..shapes import Shape
from ..shapes.registry import kinds_with


def pad3(a):
    """``(n, d)`` float rows as ``(n, 3)`` float64, trailing components zero.

    >>> pad3(np.array([[1.0, 2.0]]))
    array([[1., 2., 0.]])
    """
    a = np.asarray(a, dtype=np.float64)
    out = np.zeros((a.shape[0], 3))
    out[:, :a.shape[1]] = a
    return out


def angle_quaternion(angle):
    """Angles [rad] about z, shape ``(n,)`` or ``(n, 1)``, as ``(n, 4)`` quaternions
    ``(w, x, y, z)``: the orientation of 2D bodies in the form glyphs take.

    >>> angle_quaternion(np.array([[np.pi]])).round(12) + 0.0
    array([[0., 0., 0., 1.]])
    """
    half = 0.5 * np.asarray(angle, dtype=np.float64).reshape(-1)
    q = np.zeros((half.size, 4))
    q[:, 0], q[:, 3] = np.cos(half), np.sin(half)
    return q


def wall_patches(wall_pos, wall_normal, centre, half):
    """Planes drawn as finite patches for viewers.

    Each plane (a point ``wall_pos`` and a normal ``wall_normal``, ``(nw, d)`` [m]
    and [-]) becomes a square of half-width ``half`` [m] (3D; corners counter-clockwise
    seen from the side the normal points to) or a segment of half-length ``half``
    (2D), centred on the projection of ``centre`` (d,) [m] onto the plane.

    Returns
    -------
    points : (4 nw, 3) or (2 nw, 3) float64 [m]
    cells : (nw, 4) or (nw, 2) int32, rows of ``points``

    >>> p, c = wall_patches(np.zeros((1, 2)), np.array([[0.0, 1.0]]), np.ones(2), 0.5)
    >>> p.tolist(), c.tolist()
    ([[1.5, 0.0, 0.0], [0.5, 0.0, 0.0]], [[0, 1]])
    """
    wall_pos = np.asarray(wall_pos, dtype=np.float64)
    nw, d = wall_pos.shape
    n = np.asarray(wall_normal, dtype=np.float64)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    foot = centre - np.einsum("wi,wi->w", centre - wall_pos, n)[:, None] * n
    if d == 2:
        t = np.stack([-n[:, 1], n[:, 0]], axis=1)
        corners = np.stack([foot - half * t, foot + half * t], axis=1)
    else:
        axis = np.eye(3)[np.argmin(np.abs(n), axis=1)]  # the axis least along n
        t1 = np.cross(n, axis)
        t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
        t2 = np.cross(n, t1)  # (t1, t2, n) right-handed
        corners = np.stack([foot + half * (s1 * t1 + s2 * t2) for s1, s2 in
                            ((-1, -1), (1, -1), (1, 1), (-1, 1))], axis=1)
    k = corners.shape[1]
    cells = np.arange(nw * k, dtype=np.int32).reshape(nw, k)
    return pad3(corners.reshape(nw * k, d)), cells


#: shape kinds drawn as surfaces: those whose shape-table row holds vertices
SURFACE_KINDS = kinds_with("polytope")


def shape_surfaces(bodies):
    """World-frame triangle surfaces of the boxes, polygons and polyhedra of ``bodies``.

    Vertex ``v`` of body ``b`` (shape row ``s``) sits at
    ``pos[b] + R(rot[b]) @ (scale[s] * verts[v])``. 3D shapes bring their boundary
    triangles (``ShapeTable.tris``); a 2D polygon (or rectangle) is fanned from its
    first vertex. A compound draws each of its polytope parts. Bodies come in ascending
    index order, each with a contiguous block of points and of triangles. Custom shapes
    and spheres (no vertices) are left out.

    Parameters
    ----------
    bodies : dem.Bodies

    Returns
    -------
    dict
        ``points`` (np, 3) float64 [m], ``cells`` (nt, 3) int32 rows of ``points``,
        ``body`` (nt,) int32 body indices, ``vel`` (nt, 3) float64 [m/s] the body's
        velocity (z = 0 in 2D). Empty arrays when there is nothing to draw.
    """
    t, d = bodies.table, bodies.dim
    ids = np.flatnonzero(np.isin(bodies.kind, SURFACE_KINDS) & (bodies.shape >= 0))
    rows = bodies.shape[ids].astype(np.int64)
    pos3 = np.zeros((bodies.n, 3))
    pos3[:, :d] = bodies.pos
    place = pos3[ids]  # each drawn piece: its origin and rotation in the world
    turn = rotation_matrices(bodies.rot[ids])
    comp = np.flatnonzero(bodies.kind == Shape.COMPOUND)
    if comp.size:  # a compound draws its polytope parts
        crow = bodies.shape[comp].astype(np.int64)
        count = t.cstart[crow + 1] - t.cstart[crow]
        owner = np.repeat(comp, count)
        pool = np.concatenate([np.arange(t.cstart[s], t.cstart[s + 1]) for s in crow])
        poly = t.part_row[pool] >= 0
        owner, pool = owner[poly], pool[poly]
        body_turn = rotation_matrices(bodies.rot[owner])
        part_rot = t.part_rot[pool] if d == 3 else t.part_rot[pool, :1]
        ids = np.concatenate([ids, owner])
        rows = np.concatenate([rows, t.part_row[pool]])
        place = np.vstack([place, pos3[owner] + np.einsum("bij,bj->bi", body_turn,
                                                          t.part_off[pool])])
        turn = np.concatenate([turn, body_turn @ rotation_matrices(part_rot)])
        order = np.argsort(ids, kind="stable")
        ids, rows, place, turn = ids[order], rows[order], place[order], turn[order]
    n_verts = t.vstart[rows + 1] - t.vstart[rows]
    n_tris = (t.tstart[rows + 1] - t.tstart[rows]) if d == 3 else n_verts - 2
    keep = (n_verts >= 3) & (n_tris > 0)
    ids, rows, n_verts, n_tris = ids[keep], rows[keep], n_verts[keep], n_tris[keep]
    place, turn = place[keep], turn[keep]
    p_off = np.concatenate(([0], np.cumsum(n_verts)))
    c_off = np.concatenate(([0], np.cumsum(n_tris)))
    points = np.zeros((p_off[-1], 3))
    cells = np.zeros((c_off[-1], 3), np.int32)
    for s in np.unique(rows):
        here = np.flatnonzero(rows == s)  # pieces sharing shape row s
        local = t.scale[s] * t.verts[t.vstart[s]:t.vstart[s + 1]]
        world = place[here, None, :] + np.einsum("bij,vj->bvi", turn[here], local)
        points[p_off[here][:, None] + np.arange(local.shape[0])] = world
        if d == 3:
            tris = t.tris[t.tstart[s]:t.tstart[s + 1]]
        else:
            k = np.arange(1, local.shape[0] - 1)
            tris = np.stack([np.zeros_like(k), k, k + 1], axis=1)
        cells[c_off[here][:, None] + np.arange(tris.shape[0])] = (
            p_off[here][:, None, None] + tris[None])
    body = np.repeat(ids, n_tris).astype(np.int32)
    vel = np.zeros((body.size, 3))
    vel[:, :d] = bodies.vel[body]
    return {"points": points, "cells": cells, "body": body, "vel": vel}
