"""ContactModel: which law acts between which bodies, resolved once at set-up.

Two buckets exist for sphere scenes: sphere-sphere and sphere-wall. Each bucket has one
law kind (a compile-time constant of the time-step loop) and a per-material-pair
parameter table ``params[mat_i, mat_j]`` that the kernels index. A material pair that
occurs in the scene but has no law is an error at set-up, naming the pair.
"""

import math

import numpy as np

from .laws import Law
from .laws.dispatch import check_built
from .rolling import N_HIST as N_HIST_ROLLING


class ContactModel:
    """Laws for sphere-sphere and sphere-wall contacts.

    Parameters
    ----------
    law : Law or dict
        One law for every pair of materials, or ``{(mat_a, mat_b): Law}`` (unordered
        keys; every value of one kind, e.g. all :class:`LinearSpring`).
    wall_law : Law or dict, optional
        Law for sphere-wall contacts (default: ``law``). Keys are
        ``(sphere material, wall material)``.

    Examples
    --------
    >>> from dem.contact.laws import LinearSpring
    >>> model = ContactModel(LinearSpring(kn=1e5, kt=5e4, mu=0.3))
    >>> model.table("pp", 2).shape
    (2, 2, 7)
    """

    def __init__(self, law, wall_law=None):
        self.laws = {"pp": self._normalise(law, "law"),
                     "pw": self._normalise(law if wall_law is None else wall_law, "wall_law")}
        #: whether any law has rolling resistance: the loop then carries it for every
        #: contact (laws without it get zero parameters), in longer history rows
        self.rolling = any(v.rolling is not None for bucket in self.laws.values()
                           for v in bucket.values())
        #: columns of a history row: the widest law's own, then the rolling state
        self.n_hist = (max(v.n_hist for bucket in self.laws.values() for v in bucket.values())
                       + (N_HIST_ROLLING if self.rolling else 0))

    @staticmethod
    def _normalise(law, name):
        if isinstance(law, Law):
            check_built(law)
            return {None: law}
        if isinstance(law, dict) and law:
            out = {}
            kinds = {type(v) for v in law.values()}
            if len(kinds) != 1 or not all(isinstance(v, Law) for v in law.values()):
                raise ValueError(f"{name}: every material pair of a bucket needs the same law kind")
            for (a, b), v in law.items():
                out[(int(a), int(b))] = v
            for v in out.values():
                check_built(v)
            return out
        raise TypeError(f"{name} must be a Law or a dict {{(mat_a, mat_b): Law}}, got {law!r}")

    def kind(self, bucket):
        """The law class of a bucket ('pp' or 'pw')."""
        return type(next(iter(self.laws[bucket].values())))

    def law_for(self, bucket, a, b):
        laws = self.laws[bucket]
        if None in laws:
            return laws[None]
        if (a, b) in laws:
            return laws[(a, b)]
        if bucket == "pp" and (b, a) in laws:
            return laws[(b, a)]
        return None

    def table(self, bucket, n_mat):
        """Parameter table (n_mat, n_mat, n_param) float64; NaN rows where no law is set."""
        proto = next(iter(self.laws[bucket].values()))
        t = np.full((n_mat, n_mat, proto.full_row(self.rolling).size), np.nan)
        for a in range(n_mat):
            for b in range(n_mat):
                law = self.law_for(bucket, a, b)
                if law is not None:
                    t[a, b] = law.full_row(self.rolling)
        return t

    def check(self, bodies, mesh_materials=()):
        """Fail at set-up, naming every material pair present that has no law (the
        walls' materials: the planes' and ``mesh_materials``, those of the triangle-mesh
        walls)."""
        from ..shapes import Shape

        if self.rolling and bodies.has_shapes:
            raise ValueError("rolling resistance acts between spheres and disks (and "
                             "walls), not on level-set shapes")
        sph = np.unique(bodies.mat_id[bodies.kind != Shape.PLANE])
        wal = np.unique(np.concatenate([bodies.mat_id[bodies.kind == Shape.PLANE],
                                        np.asarray(mesh_materials, np.int64)]))
        missing = [("particle-particle", a, b) for a in sph for b in sph
                   if a <= b and self.law_for("pp", a, b) is None]
        missing += [("particle-wall", a, b) for a in sph for b in wal
                    if self.law_for("pw", a, b) is None]
        if missing:
            names = ", ".join(f"{k} materials ({a}, {b})" for k, a, b in missing)
            raise ValueError(f"no contact law for {names}")

    def modes(self, bodies, m_min):
        """``(family, k [N/m], zeta [-])`` of every law's normal and tangential contact
        mode: the largest stiffness a contact reaches (the tangential one times its
        rotational coupling) and the damping ratio for the lightest pair (effective mass
        ``m_min / 2`` [kg]: the most damped)."""
        from ..shapes import Shape

        r = bodies.radius[bodies.kind != Shape.PLANE]
        r_ref = float(r.min()) if r.size else 1.0
        rot = ROTATION_COUPLING[bodies.dim]
        out = []
        for bucket in ("pp", "pw"):
            for law in self.laws[bucket].values():
                kn = law.critical_stiffness(r_ref)
                ks = law.stiffness(law_overlap(law, r_ref), r_ref, law.row())[1]
                zeta_n, zeta_t = (law.damping_ratios(0.5 * m_min, rot)
                                  if math.isfinite(m_min) else (0.0, 0.0))
                out += [("normal", kn, zeta_n), ("tangential", rot * ks, zeta_t)]
                if law.rolling is not None:  # a body turning against the rolling spring
                    out.append(("rolling", law.rolling.stiffness_factor(bodies.dim) * kn,
                                law.rolling.eta_roll))
        return out

    def max_damping_ratio(self, bodies, m_min):
        """Largest damping ratio [-] of any law's contact modes, for the lightest pair
        (effective mass ``m_min / 2`` [kg]: the most damped)."""
        return max(z for _, _, z in self.modes(bodies, m_min))

    def max_stiffness(self, bodies):
        """Largest normal or rotation-coupled tangential stiffness [N/m] in the scene."""
        return max(k for _, k, _ in self.modes(bodies, math.inf))


#: a tangential spring acts on translation and rotation: its mode's stiffness counts
#: ``1 + m r^2 / I`` times, 3.5 for a solid sphere, 3 for a disk
ROTATION_COUPLING = {2: 3.0, 3: 3.5}


def law_overlap(law, r_ref):
    return getattr(law, "overlap_ref", 0.05) * r_ref
