"""Slow, obvious pure-numpy references for the DEM kernels, and seeded configurations.

Everything here is O(n^2) numpy written from the physics, not from the kernels: the
compiled loops are checked against it on seeded random scenes (``tests/dem``).

Conventions (``docs/conventions.md``): overlap > 0 in contact; the contact normal points
from the home body ``i`` to its neighbour ``j`` (for a wall: from the sphere into the
wall); the contact point lies halfway through the overlap; the law gives the force on
``j`` and ``i`` gets the opposite. 2D scenes are embedded in 3D with ``z = 0`` and the
spin along ``z``.
"""

import math

import numpy as np


# ----------------------------------------------------------------------- configurations
def lattice_spheres(rng, n, dim, spacing, jitter=0.0):
    """``n`` centres on a jittered square/cubic lattice of ``spacing`` [m].

    The lattice is the smallest cube of sites holding ``n``; each site is displaced by a
    uniform random vector of at most ``jitter * spacing`` per axis. Returns (n, dim).
    """
    side = math.ceil(n ** (1.0 / dim) - 1e-9)
    grid = np.stack(np.meshgrid(*[np.arange(side)] * dim, indexing="ij"), -1).reshape(
        -1, dim
    )
    pos = spacing * grid[:n].astype(np.float64)
    return pos + jitter * spacing * rng.uniform(-1.0, 1.0, size=pos.shape)


# --------------------------------------------------------------------------- geometry
def minimum_image(dx, lo=None, hi=None, periodic=None):
    """Shift separation vectors ``dx`` (..., d) to their nearest periodic image.

    Returns ``(dx_min, img)`` with ``dx_min = dx + img * L`` and ``img`` integer.
    """
    dx = np.array(dx, dtype=np.float64)
    img = np.zeros(dx.shape, dtype=np.int64)
    if periodic is None or not np.any(periodic):
        return dx, img
    length = np.asarray(hi, dtype=np.float64) - np.asarray(lo, dtype=np.float64)
    for a in np.flatnonzero(periodic):
        img[..., a] = -np.rint(dx[..., a] / length[a]).astype(np.int64)
        dx[..., a] += img[..., a] * length[a]
    return dx, img


def sphere_pairs(pos, radius, skin, lo=None, hi=None, periodic=None):
    """Every pair ``i < j`` closer than ``r_i + r_j + skin`` (minimum image).

    Returns a set of tuples ``(i, j, *img)``: ``img`` is the periodic image of ``j``
    seen from ``i`` (zeros on open axes).
    """
    n = pos.shape[0]
    i, j = np.triu_indices(n, k=1)
    dx, img = minimum_image(pos[j] - pos[i], lo, hi, periodic)
    close = np.sum(dx * dx, axis=1) < (radius[i] + radius[j] + skin) ** 2
    return {
        (int(a), int(b), *map(int, c))
        for a, b, c in zip(i[close], j[close], img[close], strict=True)
    }


def cell_pairs(pos, radius, h, cut_extra=0.0, reach=3):
    """Every pair ``i < j`` of a periodic cell with matrix ``h`` (columns: edges)
    closer than ``r_i + r_j + cut_extra`` over all images ``|n_a| <= reach``.

    Returns ``{(i, j): distance}`` (a pair seen through two images is an error).
    """
    n, d = pos.shape
    grids = np.stack(np.meshgrid(*[np.arange(-reach, reach + 1)] * d, indexing="ij"),
                     -1).reshape(-1, d)
    shifts = grids @ np.asarray(h).T
    out = {}
    for i in range(n):
        for j in range(i + 1, n):
            dist = np.linalg.norm(pos[j] - pos[i] + shifts, axis=1)
            hit = np.flatnonzero(dist < radius[i] + radius[j] + cut_extra)
            assert hit.size <= 1, "a pair touches through two images: cell too small"
            if hit.size:
                out[(i, j)] = float(dist[hit[0]])
    return out


def wall_pairs(pos, radius, wall_point, wall_normal, skin):
    """Every (sphere, wall) pair with a gap ``(x - p) . n - r`` below ``skin``."""
    out = set()
    for w in range(wall_point.shape[0]):
        gap = (pos - wall_point[w]) @ wall_normal[w] - radius
        out |= {(int(s), w) for s in np.flatnonzero(gap < skin)}
    return out


def _as3(a):
    """(n, d) -> (n, 3), zero-padded."""
    a = np.asarray(a, dtype=np.float64)
    out = np.zeros((a.shape[0], 3))
    out[:, : a.shape[1]] = a
    return out


def _spin3(w):
    """Angular velocity (n, 1) in 2D or (n, 3) in 3D -> (n, 3)."""
    w = np.asarray(w, dtype=np.float64)
    if w.shape[1] == 3:
        return w.copy()
    out = np.zeros((w.shape[0], 3))
    out[:, 2] = w[:, 0]
    return out


# --------------------------------------------------------------------------- linear law
def damping_ratio(restitution):
    """Damping ratio [-] of the linear dashpot that rebounds with ``restitution``.

    Inverts ``e = exp(-pi zeta / sqrt(1 - zeta^2))`` (tension allowed, contact ends
    when the overlap returns to zero).
    """
    le = math.log(restitution)
    return -le / math.sqrt(math.pi**2 + le**2)


def linear_law(ov, n, v_rel, m_eff, law, spring=None):
    """Force on ``j`` (c, 3) of linear spring-dashpot contacts with a Coulomb cap
    ``mu max(fn, 0)``.

    ``ov`` (c,) overlaps [m], ``n`` (c, 3) unit normals i -> j, ``v_rel`` (c, 3)
    velocity of j relative to i at the contact point [m/s], ``m_eff`` (c,) [kg];
    ``law`` a sequence of per-contact objects with ``kn, kt, gamma_n, gamma_t,
    restitution, mu``; ``spring`` (c, 3) tangential elongations [m] (zero by default).
    Returns ``(force, is_sliding)``.
    """
    c = ov.shape[0]
    kn = np.array([lw.kn for lw in law])
    kt = np.array([lw.kt for lw in law])
    gn = np.array([lw.gamma_n for lw in law])
    gt = np.array([lw.gamma_t for lw in law])
    mu = np.array([lw.mu for lw in law])
    zeta = np.array([damping_ratio(lw.restitution) for lw in law])
    s = np.zeros((c, 3)) if spring is None else spring
    vn = np.sum(v_rel * n, axis=1)
    vt = v_rel - vn[:, None] * n
    fn = kn * ov - (gn + 2.0 * zeta * np.sqrt(kn * m_eff)) * vn
    ft = -kt[:, None] * s - gt[:, None] * vt
    ft_norm = np.linalg.norm(ft, axis=1)
    cap = mu * np.maximum(fn, 0.0)  # a contact the dashpot pulls takes no friction
    sliding = ft_norm > cap
    scale = np.where(sliding, cap / np.where(ft_norm > 0.0, ft_norm, 1.0), 1.0)
    return fn[:, None] * n + scale[:, None] * ft, sliding


def linear_forces(
    pos,
    vel,
    ang_vel,
    radius,
    mass,
    mat_id,
    law_of,
    walls=None,
    gravity=None,
    lo=None,
    hi=None,
    periodic=None,
):
    """Force (n, d) [N] and torque (n, 1 or 3) [N m] on every sphere, the O(n^2) way.

    Parameters
    ----------
    pos, vel : (n, d) arrays [m], [m/s]; ang_vel : (n, 1) in 2D, (n, 3) in 3D [rad/s]
    radius, mass : (n,) [m], [kg]; mat_id : (n,) int
    law_of : callable ``(bucket, mat_a, mat_b) -> law`` with bucket "pp" or "pw"
    walls : dict of arrays ``point``, ``normal`` (unit, free side), ``vel``, ``mat_id``
    gravity : (d,) [m/s^2]
    lo, hi, periodic : periodic box (minimum image on periodic axes)

    Returns ``(force, torque, stats)``, ``stats`` counting contacts and sliding ones.
    """
    n, d = pos.shape
    x, v, w = _as3(pos), _as3(vel), _spin3(ang_vel)
    force = np.zeros((n, 3))
    torque = np.zeros((n, 3))
    stats = {"contacts": 0, "sliding": 0}

    i, j = np.triu_indices(n, k=1)
    dx, _ = minimum_image(pos[j] - pos[i], lo, hi, periodic)
    dx = _as3(dx)
    dist = np.linalg.norm(dx, axis=1)
    ov = radius[i] + radius[j] - dist
    t = ov > 0.0
    i, j, dx, dist, ov = i[t], j[t], dx[t], dist[t], ov[t]
    if i.size:
        nrm = dx / dist[:, None]
        arm_i = (radius[i] - 0.5 * ov)[:, None] * nrm  # centre of i -> contact point
        arm_j = -(radius[j] - 0.5 * ov)[:, None] * nrm  # centre of j -> contact point
        v_rel = (v[j] + np.cross(w[j], arm_j)) - (v[i] + np.cross(w[i], arm_i))
        m_eff = mass[i] * mass[j] / (mass[i] + mass[j])
        laws = [law_of("pp", a, b) for a, b in zip(mat_id[i], mat_id[j], strict=True)]
        f, sliding = linear_law(ov, nrm, v_rel, m_eff, laws)
        np.add.at(force, j, f)
        np.add.at(force, i, -f)
        np.add.at(torque, j, np.cross(arm_j, f))
        np.add.at(torque, i, np.cross(arm_i, -f))
        stats["contacts"] += i.size
        stats["sliding"] += int(sliding.sum())

    if walls is not None:
        for k in range(len(walls["point"])):
            nw = _as3(walls["normal"][k][None, :])[0]
            gap = (x - _as3(walls["point"][k][None, :])) @ nw
            ov = radius - gap
            s = np.flatnonzero(ov > 0.0)
            if not s.size:
                continue
            nrm = np.repeat(-nw[None, :], s.size, axis=0)  # sphere -> wall
            arm = (radius[s] - 0.5 * ov[s])[:, None] * nrm
            v_wall = _as3(walls["vel"][k][None, :])
            v_rel = v_wall - (v[s] + np.cross(w[s], arm))
            laws = [law_of("pw", a, walls["mat_id"][k]) for a in mat_id[s]]
            f, sliding = linear_law(ov[s], nrm, v_rel, mass[s], laws)
            np.add.at(force, s, -f)
            np.add.at(torque, s, np.cross(arm, -f))
            stats["contacts"] += s.size
            stats["sliding"] += int(sliding.sum())

    if gravity is not None:
        force += mass[:, None] * _as3(np.asarray(gravity)[None, :])
    torque = torque[:, 2:3] if d == 2 else torque
    return force[:, :d], torque, stats


# --------------------------------------------------------------------------- observable
def momenta(pos, vel, ang_vel, mass, inertia):
    """Linear momentum (3,) and angular momentum about the origin (3,) with spin."""
    x, v, w = _as3(pos), _as3(vel), _spin3(ang_vel)
    p = np.sum(mass[:, None] * v, axis=0)
    spin = _spin3(inertia) * w if inertia.shape[1] == 3 else w * inertia[:, :1]
    ell = np.sum(np.cross(x, mass[:, None] * v), axis=0) + np.sum(spin, axis=0)
    return p, ell


def periodic_homogenisation(pos, vel, mass, radius, hmat, pairs, img, fpair, kn, kt,
                            volume, geometry=None):
    """Love-Weber stress, eq 29 tangent, fabric and unbalanced ratio of a periodic
    packing, written out contact by contact.

    ``pairs``/``img`` are candidate pairs and the periodic image of j; ``fpair`` the
    force on j; ``kn``/``kt`` scalars (a linear law). ``geometry``: the contact rows
    (overlap, normal, point) of level-set shapes, which then decide touching and the
    normal (the branch still joins the centres). Returns a dict.
    """
    n, d = pos.shape
    sig = np.zeros((d, d))
    cmat = np.zeros((d, d, d, d))
    fabric = np.zeros((d, d))
    net = np.zeros((n, d))
    degree = np.zeros(n, int)
    norms = []
    for k, (i, j) in enumerate(pairs):
        branch = pos[j] - pos[i] + hmat @ img[k]
        dist = np.linalg.norm(branch)
        if geometry is not None:
            if geometry[k, 0] <= 0.0:
                continue
            nrm = geometry[k, 1:1 + d]
        elif radius[i] + radius[j] - dist <= 0.0:
            continue
        else:
            nrm = branch / dist
        f = fpair[k]
        sig -= np.outer(f, branch)
        net[i] -= f
        net[j] += f
        degree[[i, j]] += 1
        norms.append(np.linalg.norm(f))
        fabric += np.outer(nrm, nrm)
        for a in range(d):
            for b in range(d):
                for c in range(d):
                    for e in range(d):
                        s = kn * nrm[a] * nrm[c] + kt * ((a == c) - nrm[a] * nrm[c])
                        cmat[a, b, c, e] += s * branch[b] * branch[e]
    for p in range(n):
        sig -= mass[p] * np.outer(vel[p], vel[p])
    n_c = len(norms)
    return {"stress": 0.5 * (sig + sig.T) / volume, "tangent": cmat / volume,
            "fabric": fabric / max(n_c, 1), "n_contacts": n_c,
            "coordination": 2.0 * n_c / n, "rattlers": int(np.sum(degree < 2)),
            "unbalanced": np.linalg.norm(net, axis=1).mean() / np.mean(norms)}
