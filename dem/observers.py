"""Triggers and observers: read-only views of a running simulation.

An observer has a ``trigger`` (when it fires) and is called with the simulation after
the step on which the trigger fires. Observers never change the state.

- :class:`ParticleTracker`: position, velocity, orientation, angular velocity of chosen bodies;
- :class:`CollectionTracker`: homogenised Cauchy stress (paper eq 24) and contact-stiffness
  tangent (eq 29) of a collection of bodies;
- :class:`EnergyTracker`: kinetic, rotational, contact elastic, gravitational, wall work
  and dissipated energy;
- :class:`Record`: any scalar or array function of the simulation.
"""

import numpy as np

from .contact.laws import contact_energy, contact_stiffness
from .contact.rolling import COL_MOMENT, rolling_energy
from .contact.rolling import N_PARAM as ROLLING_PARAMS
from .rotation import body_frame, world_frame
from .shapes import Shape


class Periodic:
    """Fires on steps ``phase, phase + every, ...``.

    >>> t = Periodic(10)
    >>> t(20), t(25), t.next_after(25)
    (True, False, 30)
    """

    def __init__(self, every, phase=0):
        self.every, self.phase = int(every), int(phase)
        if self.every < 1:
            raise ValueError(f"every must be >= 1, got {every}")

    def __call__(self, step):
        return step >= self.phase and (step - self.phase) % self.every == 0

    def next_after(self, step):
        if step < self.phase:
            return self.phase
        return step + self.every - (step - self.phase) % self.every


class _Series:
    """Observer base: a trigger and a time series of records."""

    def __init__(self, every):
        self.trigger = every if hasattr(every, "next_after") else Periodic(every)
        self.steps = []
        self.times = []

    def _stamp(self, sim):
        self.steps.append(sim.step)
        self.times.append(sim.time)


class Record(_Series):
    """Records ``fn(sim)`` whenever the trigger fires; values in ``self.values``."""

    def __init__(self, fn, every=1):
        super().__init__(every)
        self.fn = fn
        self.values = []

    def __call__(self, sim):
        self._stamp(sim)
        v = self.fn(sim)
        self.values.append(np.array(v, copy=True) if isinstance(v, np.ndarray) else v)


class ParticleTracker(_Series):
    """Position [m], velocity [m/s], orientation and angular velocity [rad/s] of ``ids``."""

    def __init__(self, ids, every=1):
        super().__init__(every)
        self.ids = np.atleast_1d(np.asarray(ids, dtype=np.int64))
        self.pos, self.vel, self.rot, self.ang_vel = [], [], [], []

    def __call__(self, sim):
        b = sim.bodies
        self._stamp(sim)
        self.pos.append(b.pos[self.ids].copy())
        self.vel.append(b.vel[self.ids].copy())
        self.rot.append(b.rot[self.ids].copy())
        self.ang_vel.append(b.ang_vel[self.ids].copy())

    def as_arrays(self):
        """Dict of (n_records, n_ids, ...) arrays."""
        return {k: np.array(getattr(self, k)) for k in ("pos", "vel", "rot", "ang_vel")} | {
            "step": np.array(self.steps), "time": np.array(self.times)}


def contact_summary(sim):
    """Touching contacts of a primed simulation.

    Returns a dict with, per contact ``c`` (n_c rows): ``i``, ``j`` (home body and
    neighbour; j is a wall for wall contacts), ``normal`` (d,) from i to j, ``overlap``
    [m], ``x1``/``x2`` (d,) the points of i and j deepest into the other [m], ``branch``
    (d,) the vector from the centre of i to the centre of j, periodic image included
    (sphere-sphere) or to the contact point times two (walls), ``force`` (d,) on j [N],
    ``arm_i``/``arm_j`` (d,) from each centre to the contact point (``arm_j`` zero for
    walls), ``kn``/``kt`` the law's tangent stiffness [N/m], ``is_wall`` bool (triangle-
    mesh walls too: their ``j`` is ``-1 - `` the wall's index in ``mesh_walls``), and
    ``moment`` (r,) the rolling and twisting moment on j [N m] (2D: about z; i gets the
    opposite; zero without rolling resistance, :mod:`dem.contact.rolling`).
    """
    b, nl = sim.bodies, sim.neighbors
    d = b.dim
    out = {k: [] for k in ("i", "j", "normal", "overlap", "x1", "x2", "branch", "force",
                           "arm_i", "arm_j", "kn", "kt", "is_wall", "moment")}
    if sim.shaped:
        _shape_summary(sim, out)
        return _concatenate(out, d)
    # sphere-sphere
    p, img = nl.pairs, nl.img
    if p.shape[0]:
        i, j = p[:, 0], p[:, 1]
        shift = img @ sim.image_matrix.T
        dx = b.pos[j] - b.pos[i] + shift
        dist = np.linalg.norm(dx, axis=1)
        ov = b.radius[i] + b.radius[j] - dist
        t = ov > 0.0
        i, j, dx, dist, ov = i[t], j[t], dx[t], dist[t], ov[t]
        n = dx / dist[:, None]
        ri, rj = b.radius[i], b.radius[j]
        r_eff = ri * rj / (ri + rj)
        kn, kt = _stiffness(sim, "pp", ov, r_eff, b.mat_id[i], b.mat_id[j])
        out["i"].append(i), out["j"].append(j), out["normal"].append(n)
        out["overlap"].append(ov)
        out["x1"].append(b.pos[i] + ri[:, None] * n)
        out["x2"].append(b.pos[i] + dx - rj[:, None] * n)
        out["branch"].append(dx), out["force"].append(sim.pair_state.fpair[t])
        out["arm_i"].append((ri - 0.5 * ov)[:, None] * n)
        out["arm_j"].append(-(rj - 0.5 * ov)[:, None] * n)
        out["kn"].append(kn), out["kt"].append(kt)
        out["is_wall"].append(np.zeros(i.size, bool))
        out["moment"].append(_moments(sim, sim.pair_state.hist[t], 1.0))
    wp = nl.wall_pairs
    if wp.shape[0]:
        i, w = wp[:, 0], wp[:, 1]
        nw = b.normal[w]
        gap = np.einsum("ij,ij->i", b.pos[i] - b.pos[w], nw)
        ov = b.radius[i] - gap
        t = ov > 0.0
        i, w, nw, ov = i[t], w[t], nw[t], ov[t]
        n = -nw
        ri = b.radius[i]
        kn, kt = _stiffness(sim, "pw", ov, ri, b.mat_id[i], b.mat_id[w])
        arm = (ri - 0.5 * ov)[:, None] * n
        out["i"].append(i), out["j"].append(w), out["normal"].append(n)
        out["overlap"].append(ov)
        out["x1"].append(b.pos[i] + ri[:, None] * n)
        out["x2"].append(b.pos[i] + (ri - ov)[:, None] * n)
        out["branch"].append(2.0 * arm), out["force"].append(-sim.wall_state.wforce[t])
        out["arm_i"].append(arm), out["arm_j"].append(np.zeros_like(arm))
        out["kn"].append(kn), out["kt"].append(kt)
        out["is_wall"].append(np.ones(i.size, bool))
        # the wall rows keep the moment on the body: the wall gets the opposite
        out["moment"].append(_moments(sim, sim.wall_state.whist[t], -1.0))
    if getattr(sim, "has_mesh", False):
        _mesh_summary(sim, out)
    return _concatenate(out, d)


def _mesh_geometry(sim, m):
    """Centre-to-contact vectors, overlaps and radii of mesh contacts ``m``
    (:meth:`dem.Simulation.mesh_contacts`): the contact point is the middle of the
    overlap, on the line from the centre, at ``r - ov / 2``."""
    b = sim.bodies
    i = m["sphere"]
    arm = m["point"] - b.pos[i]
    ri = b.radius[i]
    return arm, 2.0 * (ri - np.linalg.norm(arm, axis=1)), ri


def _mesh_summary(sim, out):
    """The sphere-mesh rows of :func:`contact_summary` (``j = -1 - wall index``)."""
    b = sim.bodies
    m = sim.mesh_contacts()
    if not m["sphere"].size:
        return
    i = m["sphere"]
    arm, ov, ri = _mesh_geometry(sim, m)
    n = arm / np.linalg.norm(arm, axis=1)[:, None]
    kn, kt = _stiffness(sim, "pw", ov, ri, b.mat_id[i], m["mat_id"])
    out["i"].append(i), out["j"].append(-1 - m["wall"]), out["normal"].append(n)
    out["overlap"].append(ov)
    out["x1"].append(b.pos[i] + ri[:, None] * n)
    out["x2"].append(b.pos[i] + (ri - ov)[:, None] * n)
    out["branch"].append(2.0 * arm), out["force"].append(-m["force"])
    out["arm_i"].append(arm), out["arm_j"].append(np.zeros_like(arm))
    out["kn"].append(kn), out["kt"].append(kt)
    out["is_wall"].append(np.ones(i.size, bool))
    out["moment"].append(_moments(sim, m["hist"], -1.0))


def _moments(sim, hist, sign):
    """The rolling moments [N m] recorded in history rows (zeros without rolling)."""
    r = 1 if sim.dim == 2 else 3
    if not sim.model.rolling:
        return np.zeros((hist.shape[0], r))
    first = hist.shape[1] + COL_MOMENT  # counted from the row's end
    return sign * hist[:, first:first + r]


def _concatenate(out, d):
    r = 1 if d == 2 else 3
    shapes = {"i": (0,), "j": (0,), "normal": (0, d), "overlap": (0,), "x1": (0, d),
              "x2": (0, d), "branch": (0, d), "force": (0, d), "arm_i": (0, d),
              "arm_j": (0, d), "kn": (0,), "kt": (0,), "is_wall": (0,), "moment": (0, r)}
    dtypes = {"i": np.int64, "j": np.int64, "is_wall": bool}
    return {k: (np.concatenate(v) if v else np.zeros(shapes[k], dtypes.get(k, np.float64)))
            for k, v in out.items()}


def _shape_summary(sim, out):
    """:func:`contact_summary` of a scene with level-set shapes, from the loop's
    per-contact geometry rows (overlap, normal i->j, contact point)."""
    b, nl = sim.bodies, sim.neighbors
    d = b.dim
    p = nl.pairs
    if p.shape[0]:
        t = sim.shape_state.pgeom[:, 0] > 0.0
        i, j = p[t, 0], p[t, 1]
        g = sim.shape_state.pgeom[t]
        ov, n, c = g[:, 0], g[:, 1:1 + d], g[:, 4:4 + d]
        pj = b.pos[j] + nl.img[t] @ sim.image_matrix.T
        ri, rj = sim.contact_radii()[0][t].T
        kn, kt = _stiffness(sim, "pp", ov, ri * rj / (ri + rj), b.mat_id[i], b.mat_id[j])
        out["i"].append(i), out["j"].append(j), out["normal"].append(n)
        out["overlap"].append(ov)
        out["x1"].append(c + 0.5 * ov[:, None] * n), out["x2"].append(c - 0.5 * ov[:, None] * n)
        out["branch"].append(pj - b.pos[i]), out["force"].append(sim.pair_state.fpair[t])
        out["arm_i"].append(c - b.pos[i]), out["arm_j"].append(c - pj)
        out["kn"].append(kn), out["kt"].append(kt)
        out["is_wall"].append(np.zeros(i.size, bool))
        out["moment"].append(np.zeros((i.size, 1 if d == 2 else 3)))
    wp = nl.wall_pairs
    if wp.shape[0]:
        t = sim.shape_wall_state.wgeom[:, 0] > 0.0
        i, w = wp[t, 0], wp[t, 1]
        g = sim.shape_wall_state.wgeom[t]
        ov, n, c = g[:, 0], g[:, 1:1 + d], g[:, 4:4 + d]
        kn, kt = _stiffness(sim, "pw", ov, sim.contact_radii()[1][t], b.mat_id[i],
                            b.mat_id[w])
        arm = c - b.pos[i]
        out["i"].append(i), out["j"].append(w), out["normal"].append(n)
        out["overlap"].append(ov)
        out["x1"].append(c + 0.5 * ov[:, None] * n), out["x2"].append(c - 0.5 * ov[:, None] * n)
        out["branch"].append(2.0 * arm), out["force"].append(-sim.wall_state.wforce[t])
        out["arm_i"].append(arm), out["arm_j"].append(np.zeros_like(arm))
        out["kn"].append(kn), out["kt"].append(kt)
        out["is_wall"].append(np.ones(i.size, bool))
        out["moment"].append(np.zeros((i.size, 1 if d == 2 else 3)))


def _stiffness(sim, bucket, ov, r_eff, ma, mb):
    table = sim.parameter_table(bucket)
    kn = np.empty(ov.size)
    kt = np.empty(ov.size)
    contact_stiffness(sim.model.kind(bucket).code, np.ascontiguousarray(ov),
                      np.ascontiguousarray(r_eff), table, np.ascontiguousarray(ma),
                      np.ascontiguousarray(mb), kn, kt)
    return kn, kt


def stress_and_tangent(sim, volume, ids=None, kinetic=True):
    """Homogenised Cauchy stress (d, d) [Pa] and tangent (d, d, d, d) [Pa].

    Stress (paper eq 24, tension positive): ``sigma = 1/V sum_p sum_c f_c (x) a_c``
    over the bodies ``p`` of the collection, with ``f_c`` the force on ``p`` at
    contact ``c`` and ``a_c`` the arm from the centre of ``p`` to the contact point;
    for a sphere pair inside the collection this is ``-f (x) l`` with ``l`` the
    centre-to-centre branch vector. The kinetic part ``-1/V sum m v (x) v`` is added
    when ``kinetic``. The result is symmetrised.

    Tangent (eq 29): ``C = 1/V sum_c [kn (n (x) l (x) n (x) l) + kt ((I - n n) (x) l (x) l)]``
    with index order ``C_ijkl = kn n_i l_j n_k l_l + kt (delta_ik - n_i n_k) l_j l_l``.
    """
    sim.prime()
    b = sim.bodies
    c = contact_summary(sim)
    inside = np.ones(b.n, bool) if ids is None else np.isin(np.arange(b.n), ids)
    fi = -c["force"]  # force on i
    d = b.dim
    sig = np.zeros((d, d))
    mi = inside[c["i"]]
    sig += np.einsum("ca,cb->ab", fi[mi], c["arm_i"][mi])
    mj = inside[c["j"]] & ~c["is_wall"]
    sig += np.einsum("ca,cb->ab", c["force"][mj], c["arm_j"][mj])
    if kinetic:
        free = inside & (b.kind != Shape.PLANE) & ~b.is_fixed
        sig -= np.einsum("p,pa,pb->ab", b.mass[free], b.vel[free], b.vel[free])
    sig = 0.5 * (sig + sig.T) / volume
    # tangent over contacts with at least one side in the collection
    use = mi | mj
    n, kn, kt = c["normal"][use], c["kn"][use], c["kt"][use]
    branch = c["branch"][use]
    eye = np.eye(d)
    cn = np.einsum("c,ci,cj,ck,cl->ijkl", kn, n, branch, n, branch)
    proj = eye[None] - np.einsum("ci,ck->cik", n, n)
    ct = np.einsum("c,cik,cj,cl->ijkl", kt, proj, branch, branch)
    return sig, (cn + ct) / volume


def couple_stress(sim, volume, ids=None):
    """Homogenised couple stress (r, d) [N/m] of the contact moments
    (rolling and twisting resistance, :mod:`dem.contact.rolling`).

    The moments' counterpart of :func:`stress_and_tangent`'s stress:
    ``mu = 1/V sum_p sum_c m_c (x) a_c`` over the bodies ``p`` of the collection, with
    ``m_c`` the moment on ``p`` at contact ``c`` and ``a_c`` its arm; for a sphere pair
    inside the collection this is ``-m (x) l``, ``m`` the moment on j and ``l`` the
    branch vector from i to j. ``mu[a, b]``: moment component ``a`` (2D: z only) carried
    across planes normal to ``b``, per unit area. Zero without rolling resistance.
    """
    sim.prime()
    b = sim.bodies
    c = contact_summary(sim)
    inside = np.ones(b.n, bool) if ids is None else np.isin(np.arange(b.n), ids)
    mi = inside[c["i"]]
    mj = inside[c["j"]] & ~c["is_wall"]
    mu = -np.einsum("ca,cb->ab", c["moment"][mi], c["arm_i"][mi])
    mu += np.einsum("ca,cb->ab", c["moment"][mj], c["arm_j"][mj])
    return mu / volume


def fabric_anisotropy(fabric):
    """Anisotropy ``a`` [-] of a contact fabric ``F = <n (x) n>`` (d, d): the amplitude
    of the second-order Fourier fit of the density of contact normals,
    ``E(n) ~ 1 + a_ij n_i n_j`` (Rothenburg & Bathurst 1989; Ouadfel & Rothenburg 2001),
    whose coefficients follow from the deviatoric fabric ``F' = F - I/d``:
    ``a_ij = 4 F'_ij``, ``a = sqrt(a_ij a_ij / 2)`` in 2D and ``a_ij = 15/2 F'_ij``,
    ``a = sqrt(3/2 a_ij a_ij)`` in 3D. So ``E = 1 + a cos 2(theta - theta_a)`` in 2D and
    ``1 + a (3 cos^2 theta - 1) / 3`` about an axis of symmetry in 3D: 0 for isotropic
    normals. NaN for a fabric of no contacts (trace 0 or NaN)."""
    f = np.asarray(fabric, dtype=np.float64)
    d, trace = f.shape[0], float(np.trace(f))
    if not trace > 0.0:
        return float("nan")
    dev = f / trace - np.eye(d) / d
    if d == 2:
        return float(np.sqrt(0.5 * np.sum((4.0 * dev) ** 2)))
    return float(np.sqrt(1.5 * np.sum((7.5 * dev) ** 2)))


class CollectionTracker(_Series):
    """Homogenised stress (eq 24) and tangent (eq 29) of a collection of bodies.

    Parameters
    ----------
    volume : float or callable
        Volume [m^3] (area [m^2] in 2D) of the collection, or ``volume(sim)``.
    ids : array_like, optional
        Bodies of the collection (default: all).
    every : int or trigger
    """

    def __init__(self, volume, ids=None, every=100, kinetic=True):
        super().__init__(every)
        self.volume = volume
        self.ids = None if ids is None else np.asarray(ids)
        self.kinetic = kinetic
        self.stress, self.tangent = [], []

    def __call__(self, sim):
        self._stamp(sim)
        v = self.volume(sim) if callable(self.volume) else float(self.volume)
        s, c = stress_and_tangent(sim, v, self.ids, self.kinetic)
        self.stress.append(s)
        self.tangent.append(c)


def kinetic_energy(bodies):
    """Translational and rotational kinetic energy [J] of the free bodies.

    The rotational part is ``1/2 w_b . I w_b`` with ``w_b`` the angular velocity in the
    body's principal frame.
    """
    free = ~bodies.is_fixed
    tr = 0.5 * np.sum(bodies.mass[free] * np.sum(bodies.vel[free] ** 2, axis=1))
    w = body_frame(bodies.rot[free], bodies.ang_vel[free])
    ro = 0.5 * np.sum(bodies.inertia[free] * w ** 2)
    return float(tr), float(ro)


def angular_momentum(bodies, origin=None):
    """Total angular momentum (3,) [kg m^2/s] (2D: (1,)) of the free bodies about ``origin``."""
    free = ~bodies.is_fixed
    d = bodies.dim
    x = bodies.pos[free] - (0.0 if origin is None else np.asarray(origin, np.float64))
    p = bodies.mass[free, None] * bodies.vel[free]
    spin_b = bodies.inertia[free] * body_frame(bodies.rot[free], bodies.ang_vel[free])
    if d == 2:
        orbit = x[:, 0] * p[:, 1] - x[:, 1] * p[:, 0]
        return np.array([orbit.sum() + spin_b[:, 0].sum()])
    spin = world_frame(bodies.rot[free], spin_b)
    return np.cross(x, p).sum(axis=0) + spin.sum(axis=0)


def elastic_energy(sim):
    """Elastic energy [J] stored in the contacts (normal, tangential, rolling and
    twisting springs; the rolling ones at the current normal stiffness), triangle-mesh
    walls' included."""
    sim.prime()
    b, nl = sim.bodies, sim.neighbors
    e = 0.0
    if sim.shaped:
        radii = sim.contact_radii()
        for bucket, pairs, hist, geom, tab in (
                ("pp", nl.pairs, sim.pair_state.hist, sim.shape_state.pgeom,
                 sim.parameter_table("pp")),
                ("pw", nl.wall_pairs, sim.wall_state.whist, sim.shape_wall_state.wgeom,
                 sim.parameter_table("pw"))):
            if not pairs.shape[0]:
                continue
            i, j = pairs[:, 0], pairs[:, 1]
            if bucket == "pp":
                ri, rj = radii[0].T
                r_eff = ri * rj / (ri + rj)
            else:
                r_eff = radii[1]
            e += contact_energy(sim.model.kind(bucket).code, geom[:, 0].copy(),
                                np.ascontiguousarray(r_eff), tab, b.mat_id[i], b.mat_id[j],
                                hist, np.flatnonzero(geom[:, 0] > 0.0))
        return float(e)
    for bucket, pairs, hist, tab in (
            ("pp", nl.pairs, sim.pair_state.hist, sim.parameter_table("pp")),
            ("pw", nl.wall_pairs, sim.wall_state.whist, sim.parameter_table("pw"))):
        if not pairs.shape[0]:
            continue
        law = sim.model.kind(bucket)
        i, j = pairs[:, 0], pairs[:, 1]
        if bucket == "pp":
            dx = b.pos[j] - b.pos[i] + nl.img @ sim.image_matrix.T
            ov = b.radius[i] + b.radius[j] - np.linalg.norm(dx, axis=1)
            r_eff = b.radius[i] * b.radius[j] / (b.radius[i] + b.radius[j])
        else:
            ov = b.radius[i] - np.einsum("ij,ij->i", b.pos[i] - b.pos[j], b.normal[j])
            r_eff = b.radius[i]
        e += contact_energy(law.code, ov, np.ascontiguousarray(r_eff), tab, b.mat_id[i],
                            b.mat_id[j], hist, np.flatnonzero(ov > 0.0))
        if sim.model.rolling:  # the rolling and twisting springs
            t = ov > 0.0
            ma, mb = b.mat_id[i][t], b.mat_id[j][t]
            kn = _stiffness(sim, bucket, ov[t], r_eff[t], ma, mb)[0]
            e += rolling_energy(tab[ma, mb, tab.shape[2] - ROLLING_PARAMS:], hist[t], kn,
                                r_eff[t])
    if getattr(sim, "has_mesh", False):
        e += _mesh_energy(sim)
    return float(e)


def _mesh_energy(sim):
    """Elastic energy [J] of the sphere-mesh contacts (the ``"pw"`` law, as a plane)."""
    m = sim.mesh_contacts()
    if not m["sphere"].size:
        return 0.0
    _, ov, ri = _mesh_geometry(sim, m)
    ma, mb, tab = sim.bodies.mat_id[m["sphere"]], m["mat_id"], sim.parameter_table("pw")
    e = contact_energy(sim.model.kind("pw").code, ov, ri, tab, ma, mb, m["hist"],
                       np.arange(ov.size))
    if sim.model.rolling:
        kn = _stiffness(sim, "pw", ov, ri, ma, mb)[0]
        e += rolling_energy(tab[ma, mb, tab.shape[2] - ROLLING_PARAMS:], m["hist"], kn, ri)
    return e


class EnergyTracker(_Series):
    """Energy budget [J]: kinetic, rotational, elastic, gravitational, wall work, dissipated.

    ``dissipated = wall_work - (change of kinetic + rotational + elastic + gravitational)``
    since the first record: what dashpots, friction and local damping took out.
    """

    KEYS = ("kinetic", "rotational", "elastic", "potential", "wall_work", "dissipated")

    def __init__(self, every=100):
        super().__init__(every)
        self.data = {k: [] for k in self.KEYS}
        self._e0 = None

    def __call__(self, sim):
        self._stamp(sim)
        b = sim.bodies
        tr, ro = kinetic_energy(b)
        el = elastic_energy(sim)
        free = ~b.is_fixed
        pot = -float(np.sum(b.mass[free] * (b.pos[free] @ sim.gravity)))
        work = float(sim.wall_work[0])
        total = tr + ro + el + pot
        if self._e0 is None:
            self._e0 = (total, work)
        diss = (work - self._e0[1]) - (total - self._e0[0])
        for k, v in zip(self.KEYS, (tr, ro, el, pot, work, diss), strict=True):
            self.data[k].append(v)

    def as_arrays(self):
        return {k: np.array(v) for k, v in self.data.items()} | {"step": np.array(self.steps)}
