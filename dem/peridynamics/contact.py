"""Contact of peridynamic bodies through the ordinary contact laws.

Two bodies of a :class:`~dem.peridynamics.PDSimulation` that no intact bond joins (two
fragments, a point and a DEM sphere, two solids) touch when their spheres overlap, and
a body touches a wall (a plane body) when its sphere crosses the plane. Either contact
acts through a law of :mod:`dem.contact.laws` (:class:`~dem.LinearSpring`,
:class:`~dem.HertzMindlin`, ...) with its parameter table per material pair and its
history row per contact, as in :class:`dem.Simulation`: friction, damping and the
tangential spring are the laws' own. Material points carry no rotation, so the relative
velocity is that of the centres and a contact force acts through them (no torque);
rolling resistance, which acts on rotations, is refused.

The default is :func:`default_law`: a frictionless, undamped linear spring, the elastic
penalty of the first peridynamics release.
"""

import math
from typing import NamedTuple

import numpy as np

from .._jit import kernel
from ..contact.laws import Law, LinearSpring, apply_law
from ..contact.model import ContactModel
from ..neighbors import carry_history
from ..shapes import Shape


class Contacts(NamedTuple):
    """The contacts of a peridynamic scene: candidate pairs ``cpairs`` (m, 2) int64
    sorted by ``(i, j)`` with their history rows ``hist`` (m, h) and touching flags
    ``touch`` (m,) uint8, the rows of the wall bodies ``walls`` (nw,) int64, every
    body's ``normal`` (the walls'), the history and flags of every (wall, body) pair
    ``whist`` (nw * n, h) and ``wtouch`` (row ``a * n + i``), the bodies' materials
    ``mat_id``, the laws' parameter tables ``params_pp`` and ``params_pw`` (n_mat,
    n_mat, row) and the laws' codes ``code_pp`` and ``code_pw``."""

    cpairs: np.ndarray
    hist: np.ndarray
    touch: np.ndarray
    walls: np.ndarray
    normal: np.ndarray
    whist: np.ndarray
    wtouch: np.ndarray
    mat_id: np.ndarray
    params_pp: np.ndarray
    params_pw: np.ndarray
    code_pp: int
    code_pw: int


@kernel
def bonded(start, nbr, broken, i, j):
    """Whether ``i`` and ``j`` are joined by an intact bond (binary search in i's row)."""
    lo, hi = start[i], start[i + 1]
    while lo < hi:
        mid = (lo + hi) // 2
        if nbr[mid] < j:
            lo = mid + 1
        else:
            hi = mid
    return lo < start[i + 1] and nbr[lo] == j and broken[lo] == 0


@kernel(inline=True)
def _forget(hist, k):
    for c in range(hist.shape[1]):
        hist[k, c] = 0.0


@kernel(inline=True)
def _exchange(force_out, i, j, fx, fy, fz):
    """Add the force ``f`` on j, and ``-f`` on i (2D: ``fz`` unused)."""
    force_out[i, 0] -= fx
    force_out[i, 1] -= fy
    force_out[j, 0] += fx
    force_out[j, 1] += fy
    if force_out.shape[1] == 3:
        force_out[i, 2] -= fz
        force_out[j, 2] += fz


@kernel
def contact_pass(pos, vel, mass, radius, start, nbr, broken, contacts, dt, force_out):
    """Add the contact forces [N] of the current state to ``force_out``.

    A candidate pair touches when its spheres overlap and no intact bond joins it; a
    body touches wall ``w`` when ``r_i - (x_i - x_w) . n_w > 0``. Each contact calls
    its law with the overlap, the unit normal from i to j (into the wall), the
    relative velocity of the centres, ``r_eff`` and ``m_eff`` (the masses of the
    bodies, held or free; a wall's is infinite) and ``dt`` (0 evaluates the forces
    without advancing any history); the history of a contact that is open is zeroed.
    """
    (cpairs, hist, touch, walls, wnormal, whist, wtouch, mat_id, params_pp, params_pw,
     code_pp, code_pw) = contacts
    n, d = pos.shape
    for q in range(cpairs.shape[0]):
        i, j = cpairs[q, 0], cpairs[q, 1]
        dx = pos[j, 0] - pos[i, 0]
        dy = pos[j, 1] - pos[i, 1]
        dz = pos[j, 2] - pos[i, 2] if d == 3 else 0.0
        r2 = dx * dx + dy * dy + dz * dz
        lim = radius[i] + radius[j]
        if r2 >= lim * lim or bonded(start, nbr, broken, i, j):
            if touch[q]:  # it opened: its history ends
                touch[q] = 0
                _forget(hist, q)
            continue
        touch[q] = 1
        r = math.sqrt(r2)
        inv = 1.0 / r
        vx = vel[j, 0] - vel[i, 0]
        vy = vel[j, 1] - vel[i, 1]
        vz = vel[j, 2] - vel[i, 2] if d == 3 else 0.0
        fx, fy, fz = apply_law(code_pp, lim - r, dx * inv, dy * inv, dz * inv, vx, vy, vz,
                               radius[i] * radius[j] / lim,
                               mass[i] * mass[j] / (mass[i] + mass[j]), params_pp,
                               mat_id[i], mat_id[j], hist, q, dt)
        _exchange(force_out, i, j, fx, fy, fz)
    for a in range(walls.size):
        w = walls[a]
        for i in range(n):
            row = a * n + i
            if radius[i] <= 0.0:
                continue
            h = 0.0
            for k in range(d):
                h += (pos[i, k] - pos[w, k]) * wnormal[w, k]
            ov = radius[i] - h
            if ov <= 0.0:
                if wtouch[row]:
                    wtouch[row] = 0
                    _forget(whist, row)
                continue
            wtouch[row] = 1
            vx = vel[w, 0] - vel[i, 0]
            vy = vel[w, 1] - vel[i, 1]
            vz = vel[w, 2] - vel[i, 2] if d == 3 else 0.0
            nz = -wnormal[w, 2] if d == 3 else 0.0
            fx, fy, fz = apply_law(code_pw, ov, -wnormal[w, 0], -wnormal[w, 1], nz, vx, vy,
                                   vz, radius[i], mass[i], params_pw, mat_id[i], mat_id[w],
                                   whist, row, dt)
            _exchange(force_out, i, w, fx, fy, fz)  # the law gives the force on the wall


# --------------------------------------------------------------------------- Python side
def default_law(vol, dx, material):
    """The default contact: a frictionless, undamped linear spring of stiffness
    ``E V / (2 dx^2)`` [N/m], half the stiffness of a lattice cell squeezed across its
    width, so that contact does not set the time step of a lattice scene (``V`` the
    points' mean volume [m^3], ``E`` the material's Young's modulus)."""
    return LinearSpring(kn=0.5 * material.E * vol / dx**2)


def contact_model(contact, contact_kn, default):
    """The :class:`~dem.ContactModel` of a scene from ``PDSimulation``'s ``contact``
    (a :class:`~dem.contact.laws.Law`, a ContactModel or None) and ``contact_kn`` (the
    default spring's stiffness [N/m], or None); ``default()`` gives the default law."""
    if contact is not None and contact_kn is not None:
        raise ValueError("give contact (a law) or contact_kn (the default law's "
                         "stiffness), not both")
    if contact_kn is not None:
        if not (contact_kn > 0.0 and math.isfinite(contact_kn)):
            raise ValueError(f"contact_kn must be positive and finite, got {contact_kn}")
        contact = LinearSpring(kn=float(contact_kn))
    if contact is None:
        contact = default()
    if isinstance(contact, Law):
        contact = ContactModel(contact)
    if not isinstance(contact, ContactModel):
        raise TypeError(f"contact must be a contact law (e.g. dem.LinearSpring) or a "
                        f"dem.ContactModel, got {contact!r}")
    if contact.rolling:
        raise ValueError("rolling resistance acts on rotations, and peridynamic points "
                         "carry none: use a contact law without rolling")
    return contact


class ContactState:
    """The contact state of a peridynamic scene: the model's tables, the candidate
    pairs and the history rows, pair rows carried by key across rebuilds."""

    def __init__(self, model, bodies):
        model.check(bodies)
        self.model = model
        n_mat = int(bodies.mat_id.max()) + 1 if bodies.n else 1
        self.params_pp = model.table("pp", n_mat)
        self.params_pw = model.table("pw", n_mat)
        self.code_pp = int(model.kind("pp").code)
        self.code_pw = int(model.kind("pw").code)
        self.walls = np.flatnonzero(bodies.kind == Shape.PLANE).astype(np.int64)
        self.n_hist = model.n_hist
        self.cpairs = np.zeros((0, 2), np.int64)
        self.hist = np.zeros((0, self.n_hist))
        self.touch = np.zeros(0, np.uint8)
        self.whist = np.zeros((self.walls.size * bodies.n, self.n_hist))
        self.wtouch = np.zeros(self.walls.size * bodies.n, np.uint8)

    def set_pairs(self, pairs):
        """New candidate pairs (k, 2), ``i < j``: sorted, with the history of the pairs
        that were candidates before."""
        pairs = np.asarray(pairs, np.int64).reshape(-1, 2)
        pairs = np.ascontiguousarray(pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))])
        hist = np.zeros((pairs.shape[0], self.n_hist))
        carry_history(self.cpairs, self.hist, pairs, hist)
        # a pair with history was touching; others are found by the next force pass
        self.cpairs, self.hist = pairs, hist
        self.touch = np.any(hist != 0.0, axis=1).astype(np.uint8)

    def bundle(self, bodies):
        return Contacts(self.cpairs, self.hist, self.touch, self.walls, bodies.normal,
                        self.whist, self.wtouch, bodies.mat_id, self.params_pp,
                        self.params_pw, self.code_pp, self.code_pw)

    def stiffness(self, r_ref):
        """The largest contact stiffness [N/m] of the scene's laws (normal or
        tangential), at the reference radius ``r_ref`` [m] for a nonlinear law."""
        laws = [v for bucket in self.model.laws.values() for v in bucket.values()]
        return max(law.critical_stiffness(r_ref) for law in laws)

    def empty(self, bodies):
        """A bundle with no contact (the stiffness of the bonds alone)."""
        none, flags = np.zeros((0, self.n_hist)), np.zeros(0, np.uint8)
        return Contacts(np.zeros((0, 2), np.int64), none, flags, np.zeros(0, np.int64),
                        bodies.normal, none, flags, bodies.mat_id, self.params_pp,
                        self.params_pw, self.code_pp, self.code_pw)
