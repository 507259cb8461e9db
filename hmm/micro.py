"""Micro models: the material response at one Gauss point.

Every model follows one protocol, the contract of the macro solver with its Gauss
points (YADE's FEMxDEM pattern):

``trial(G) -> (sigma, C)``
    The Cauchy stress (d, d) [Pa] and the tangent ``C_ijkl = d sigma_ij / d eps_kl``
    (d, d, d, d) [Pa] after the displacement-gradient increment ``G`` (d, d), always
    measured from the last *committed* state: a Newton iteration may call it many
    times. ``G = grad_{x_n} du`` is taken on the configuration of the last converged
    step, so ``I + G`` maps that configuration to the trial one; under the macro
    solver's small kinematics it is the symmetric strain increment ``sym grad du``.
    Stress and tangent are in the current frame: ``C`` is the response to a
    symmetric strain increment of the trial configuration; an *objective* model
    (``objective = True``) turns its stress with the material's spin on top of it.
``commit()``
    The last trial becomes the committed state (the load step converged).
``rollback()``
    Forget the trials since the last commit (the step is cut and retried).
``measures()``
    The committed state's measures, written with the fields: the names and shapes of
    :func:`measure_shapes` (``void_ratio``, ``coordination``, ``ran_dem``: 1.0 where
    the DEM ran, the contact ``fabric`` <n (x) n> and its ``anisotropy``
    (:func:`dem.observers.fabric_anisotropy`), the ``couple_stress`` [N/m] of rolling
    resistance); NaN where a model has no such thing.

Only objective models run under finite kinematics: the DEM RVE (its periodic cell
follows the whole velocity gradient, spin included), :class:`Adaptive` built with
``finite=True``, :class:`Hypoelastic` (Jaumann rate) and :class:`NeoHookean`.
:class:`LinearElastic` and :class:`Hyperbolic` are small-strain laws.

Stress is positive in tension. 2D models are plane strain.
"""

import math
import time

import numpy as np

from .tensors import polar, rotate4, rotation_power


def isotropic_tangent(dim, bulk, shear):
    """``C = K I (x) I + 2 G (I_sym - I (x) I / d)`` (d, d, d, d) [Pa].

    In 2D this is the plane-strain tangent with the 3D bulk modulus replaced by its
    in-plane value ``K = lambda + G`` (so ``K = E / (2 (1 + nu)(1 - 2 nu))``).
    """
    eye = np.eye(dim)
    ii = np.einsum("ij,kl->ijkl", eye, eye)
    sym = 0.5 * (np.einsum("ik,jl->ijkl", eye, eye) + np.einsum("il,jk->ijkl", eye, eye))
    return bulk * ii + 2.0 * shear * (sym - ii / dim)


def lame(young, poisson):
    """Lame's ``lambda`` and shear modulus ``G`` [Pa] from E and nu."""
    if not (young > 0.0 and math.isfinite(young)):
        raise ValueError(f"young must be positive and finite, got {young}")
    if not -1.0 < poisson < 0.5:
        raise ValueError(f"poisson must be in (-1, 0.5), got {poisson}")
    g = young / (2.0 * (1.0 + poisson))
    return young * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson)), g


def measure_shapes(dim):
    """The measures every micro model gives (:meth:`MicroModel.measures`), by name,
    with their shapes in ``dim`` dimensions: the contract a farm gathers by."""
    return {"void_ratio": (), "coordination": (), "ran_dem": (), "anisotropy": (),
            "fabric": (dim, dim), "couple_stress": (1 if dim == 2 else 3, dim)}


def no_measures(dim, ran_dem=False):
    """:func:`measure_shapes` filled with NaN (``ran_dem`` as given)."""
    out = {k: np.full(shape, math.nan) if shape else math.nan
           for k, shape in measure_shapes(dim).items()}
    out["ran_dem"] = float(ran_dem)
    return out


class MicroModel:
    """Base of the micro models (see the module docstring for the protocol)."""

    dim = 2
    ran_dem = False
    #: the stress turns with the material (the model may run under finite kinematics)
    objective = False

    def trial(self, deps):
        raise NotImplementedError

    def commit(self):
        raise NotImplementedError

    def rollback(self):
        raise NotImplementedError

    def measures(self):
        return no_measures(self.dim, self.ran_dem)

    def export(self):
        """The committed state as a flat dict of arrays (to move a point to another
        rank or into a checkpoint); :meth:`load` sets it on a model built the same
        way."""
        raise NotImplementedError

    def load(self, state):
        raise NotImplementedError


class _OneArrayLaw(MicroModel):
    """An analytic law whose whole state is one array: the committed
    ``self.<name>`` and the trial ``self._trial``, ``_STATE = (name, export key)``."""

    _STATE = ("stress", "stress")

    def commit(self):
        setattr(self, self._STATE[0], self._trial.copy())

    def rollback(self):
        self._trial = getattr(self, self._STATE[0]).copy()

    def export(self):
        return {self._STATE[1]: getattr(self, self._STATE[0]).copy()}

    def load(self, state):
        setattr(self, self._STATE[0], np.array(state[self._STATE[1]], dtype=np.float64))
        self.rollback()


class LinearElastic(_OneArrayLaw):
    """Isotropic linear elasticity (plane strain in 2D) about an initial stress.

    Parameters
    ----------
    young, poisson : float
        E [Pa] and nu [-].
    dim : 2 or 3
    stress0 : (d, d) array_like or float, optional
        Initial stress [Pa]; a float ``s`` means ``s I`` (``-p0`` for a confined
        packing).

    Examples
    --------
    >>> m = LinearElastic(1e6, 0.25, dim=2)
    >>> s, c = m.trial(np.diag([1e-3, 0.0]))
    >>> round(float(s[0, 0])), round(float(s[1, 1]))  # [Pa], plane strain
    (1200, 400)
    """

    def __init__(self, young, poisson, dim=2, stress0=0.0):
        lam, g = lame(young, poisson)
        self.dim = int(dim)
        self.tangent = isotropic_tangent(self.dim, lam + 2.0 * g / self.dim, g)
        s0 = np.asarray(stress0, dtype=np.float64)
        self.stress = s0 * np.eye(self.dim) if s0.ndim == 0 else s0.copy()
        self._trial = self.stress.copy()

    def trial(self, deps):
        eps = 0.5 * (deps + deps.T)
        self._trial = self.stress + np.einsum("ijkl,kl->ij", self.tangent, eps)
        return self._trial.copy(), self.tangent


class Hyperbolic(_OneArrayLaw):
    """Nonlinear elasticity with a shear modulus that softens with shear strain.

    ``sigma = sigma0 + K tr(eps) I + 2 G(g) e`` with ``e`` the deviatoric strain,
    ``g = sqrt(2 e:e)`` and ``G(g) = G0 / (1 + g / g_ref)`` (a hyperbolic
    stress-strain curve: the shear stress tends to ``G0 g_ref``). The response is
    path-independent with an exact (consistent) tangent: the reference against which
    Newton's quadratic convergence is tested.

    Parameters
    ----------
    young, poisson : float
        Small-strain E [Pa] and nu [-] (give K and G0).
    gamma_ref : float
        Reference shear strain [-].
    dim : 2 or 3
    stress0 : float or (d, d), optional
        Initial stress [Pa].
    """

    _STATE = ("strain", "strain")

    def __init__(self, young, poisson, gamma_ref, dim=2, stress0=0.0):
        lam, g0 = lame(young, poisson)
        if not gamma_ref > 0.0:
            raise ValueError(f"gamma_ref must be positive, got {gamma_ref}")
        self.dim = int(dim)
        self.bulk = lam + 2.0 * g0 / self.dim
        self.g0 = g0
        self.gamma_ref = float(gamma_ref)
        s0 = np.asarray(stress0, dtype=np.float64)
        self.stress0 = s0 * np.eye(self.dim) if s0.ndim == 0 else s0.copy()
        self.strain = np.zeros((self.dim, self.dim))
        self._trial = self.strain.copy()

    def response(self, eps):
        """Stress and tangent at total strain ``eps`` (d, d)."""
        d = self.dim
        eye = np.eye(d)
        e = eps - np.trace(eps) / d * eye
        gam = math.sqrt(2.0 * np.sum(e * e))
        g = self.g0 / (1.0 + gam / self.gamma_ref)
        sig = self.stress0 + self.bulk * np.trace(eps) * eye + 2.0 * g * e
        c = isotropic_tangent(d, self.bulk, g)
        if gam > 0.0:  # d(2 G(g) e)/d eps adds 2 G'(g) e (x) dg/deps, dg/deps = 2 e / g
            dg = -self.g0 / self.gamma_ref / (1.0 + gam / self.gamma_ref) ** 2
            c += 4.0 * dg / gam * np.einsum("ij,kl->ijkl", e, e)
        return sig, c

    def trial(self, deps):
        self._trial = self.strain + 0.5 * (deps + deps.T)
        return self.response(self._trial)

    @property
    def stress(self):
        return self.response(self.strain)[0]


def _increment(g, dim):
    """The increment ``I + G`` as an array, refused if it inverts the material."""
    f = np.eye(dim) + np.asarray(g, dtype=np.float64)
    if f.shape != (dim, dim) or not np.all(np.isfinite(f)):
        raise ValueError(f"the increment must be a finite ({dim}, {dim}) array")
    det = float(np.linalg.det(f))
    if not det > 0.0:
        raise ValueError(f"the increment inverts the material (det(I + G) = {det:.4g})")
    return f


class Hypoelastic(_OneArrayLaw):
    """Isotropic hypoelasticity with the Jaumann rate: ``sigma' = C : d``, with
    ``sigma'`` the co-rotational rate ``dsigma/dt - w sigma + sigma w``.

    An increment ``G`` is integrated in the frame of its middle (Hughes and Winget's
    midpoint rates, ``d dt + w dt = G (I + G/2)^-1``, with the rotation
    ``R = (I - w dt/2)^-1 (I + w dt/2)`` split in two halves ``R_h``):
    ``sigma_n+1 = R_h (R_h sigma_n R_h^T + C : d dt) R_h^T``. A rigid rotation turns
    the stress exactly; with a constant velocity gradient the error falls with the
    square of the step (simple shear: ``sigma_xy = G sin(gamma)``,
    ``sigma_xx = -sigma_yy = G (1 - cos(gamma))``).

    Parameters
    ----------
    young, poisson : float
        E [Pa] and nu [-] of the elastic moduli ``C``.
    dim : 2 or 3
    stress0 : float or (d, d), optional
        Initial stress [Pa].

    Examples
    --------
    >>> m = Hypoelastic(1e6, 0.25, stress0=np.diag([-1e3, 0.0]))
    >>> c, s = np.cos(np.pi / 2), np.sin(np.pi / 2)
    >>> sig, _ = m.trial(np.array([[c, -s], [s, c]]) - np.eye(2))  # a quarter turn
    >>> np.round(sig, 9).tolist()
    [[0.0, 0.0], [0.0, -1000.0]]
    """

    objective = True

    def __init__(self, young, poisson, dim=2, stress0=0.0):
        lam, g = lame(young, poisson)
        self.dim = int(dim)
        self.tangent = isotropic_tangent(self.dim, lam + 2.0 * g / self.dim, g)
        s0 = np.asarray(stress0, dtype=np.float64)
        self.stress = s0 * np.eye(self.dim) if s0.ndim == 0 else s0.copy()
        self._trial = self.stress.copy()

    def trial(self, deps):
        eye = np.eye(self.dim)
        g = _increment(deps, self.dim) - eye
        rate = np.linalg.solve((eye + 0.5 * g).T, g.T).T  # (d + w) dt at mid-step
        d = 0.5 * (rate + rate.T)
        w = 0.5 * (rate - rate.T)
        r = np.linalg.solve(eye - 0.5 * w, eye + 0.5 * w)
        half = rotation_power(r, 0.5)
        rest = r @ half.T
        mid = half @ self.stress @ half.T + np.einsum("ijkl,kl->ij", self.tangent, d)
        self._trial = rest @ mid @ rest.T
        return self._trial.copy(), self.tangent


class NeoHookean(_OneArrayLaw):
    """Compressible neo-Hookean hyperelasticity with its exact tangent.

    ``sigma = (mu (b - I) + lambda ln(J) I) / J``, ``b = F F^T``, ``J = det F``
    (plane strain in 2D: ``F_zz = 1``), with Lame's ``lambda`` and ``mu`` from the
    small-strain E and nu. The tangent is exact: for ``g = eps + w``,
    ``d sigma = C : eps + w sigma - sigma w`` with
    ``C : eps = -sigma tr(eps) + (mu (eps b + b eps) + lambda tr(eps) I) / J``.

    Parameters
    ----------
    young, poisson : float
        E [Pa] and nu [-] at small strain.
    dim : 2 or 3

    Examples
    --------
    >>> m = NeoHookean(3e6, 0.25, dim=3)
    >>> sig, _ = m.trial(np.diag([1.0, 0.0, 0.0]))  # stretch 2 with no lateral strain
    >>> round(float(sig[0, 0]))  # (mu (4 - 1) + lambda ln 2) / 2 [Pa]
    2215888
    """

    objective = True

    _STATE = ("f", "deformation")

    def __init__(self, young, poisson, dim=2):
        self.lam, self.mu = lame(young, poisson)
        self.dim = int(dim)
        self.f = np.eye(self.dim)
        self._trial = self.f.copy()

    def response(self, f):
        """Cauchy stress and tangent ``C`` at the deformation gradient ``f``."""
        d = self.dim
        e = np.eye(d)
        jac = float(np.linalg.det(f))
        b = f @ f.T
        sig = (self.mu * (b - e) + self.lam * math.log(jac) * e) / jac
        c = (-np.einsum("ij,kl->ijkl", sig, e)
             + (0.5 * self.mu * (np.einsum("ik,lj->ijkl", e, b) + np.einsum("il,kj->ijkl", e, b)
                                 + np.einsum("ik,jl->ijkl", b, e) + np.einsum("il,jk->ijkl", b, e))
                + self.lam * np.einsum("ij,kl->ijkl", e, e)) / jac)
        return sig, c

    def trial(self, deps):
        self._trial = _increment(deps, self.dim) @ self.f
        return self.response(self._trial)

    @property
    def stress(self):
        return self.response(self.f)[0]


#: why the perturbation tangent and unrelaxed calls do not go together
PERTURBATION_NEEDS_RELAX = (
    "the perturbation tangent relaxes its probes, so it needs relaxed RVE calls: from "
    "the unbalanced state an unrelaxed call leaves, a probe measures that state's "
    "relaxation, not the stiffness (with relax = false use the contact tangent)")


class DEMMicroModel(MicroModel):
    """One periodic DEM RVE (:class:`dem.rve.RVE`) at a Gauss point.

    A trial restores the committed state (a copy into preallocated arrays) unless
    nothing has moved since, applies the strain increment under strain control,
    relaxes, and returns the Love-Weber stress and the tangent (``"contact"``: eq 29;
    ``"perturbation"``: relaxed probes, costlier and exact for the relaxed state).
    ``relax=False`` skips the relaxation, YADE FEMxDEM's call (see
    :meth:`dem.rve.RVE.apply_strain`); it takes the contact tangent only.
    """

    ran_dem = True
    objective = True  # the periodic cell follows the whole velocity gradient

    def __init__(self, rve, tangent="contact", probe=1e-5, relax=True):
        if tangent not in ("contact", "perturbation"):
            raise ValueError(f"tangent must be 'contact' or 'perturbation', got {tangent!r}")
        if tangent == "perturbation" and not relax:
            raise ValueError(PERTURBATION_NEEDS_RELAX)
        self.rve = rve
        self.relax = bool(relax)
        self.dim = rve.dim
        self.tangent_method = tangent
        self.probe = float(probe)
        self._committed = rve.snapshot()
        self._moved = False
        self.stress = rve.stress()
        self._trial_stress = self.stress
        self.cost = 0.0  # seconds of the last trial
        self.steps = 0  # DEM steps of the last trial, tangent probes included

    def trial(self, deps):
        t0 = time.perf_counter()
        rve = self.rve
        if self._moved:
            rve.restore(self._committed)
        self._moved = True
        work0 = rve.steps_run
        if self.tangent_method == "contact":  # stress and tangent from one pass
            sig, c = rve.apply_strain(deps, relax=self.relax, tangent=True)
        else:
            sig = rve.apply_strain(deps, relax=self.relax)
            c = rve.tangent(self.tangent_method, self.probe, direction=deps)
        self.steps = rve.steps_run - work0  # perturbation probes included
        self._trial_stress = sig
        self.cost = time.perf_counter() - t0
        return sig, c

    def commit(self):
        self.rve.snapshot(into=self._committed)
        self._moved = False
        self.stress = self._trial_stress

    def rollback(self):
        if self._moved:
            self.rve.restore(self._committed)
            self._moved = False
        self._trial_stress = self.stress

    def export(self):
        if self._moved:
            self.rollback()
        out = {"rve/" + k: v.copy() for k, v in self._committed.items()}
        out["stress"] = np.array(self.stress, dtype=np.float64)
        return out

    def load(self, state):
        snap = {k[4:]: np.asarray(v) for k, v in state.items() if k.startswith("rve/")}
        self.rve.restore(snap)
        self._committed = self.rve.snapshot()
        self._moved = False
        self.stress = np.array(state["stress"], dtype=np.float64)
        self._trial_stress = self.stress

    def elastic_tangent(self):
        """The contact tangent of the committed state (no motion)."""
        if self._moved:
            self.rollback()
        return self.rve.tangent("contact")

    def measures(self):
        if self._moved:
            self.rollback()
        from dem.observers import fabric_anisotropy

        r = self.rve.response(tangent=False)
        d = r["stress"].shape[0]
        fabric = r["fabric"] if r["n_contacts"] > 0 else np.full((d, d), math.nan)
        couple = r.get("couple_stress")
        return {"void_ratio": r["void_ratio"], "coordination": r["coordination"],
                "ran_dem": 1.0, "fabric": fabric, "anisotropy": fabric_anisotropy(fabric),
                "couple_stress": np.full(measure_shapes(d)["couple_stress"], math.nan)
                if couple is None else couple}


def stress_ratio(sig):
    """Deviatoric over mean stress, ``q / p`` with ``p = -tr(sigma) / d`` and
    ``q = sqrt(3/2 s:s)`` (3D) or the radius of Mohr's circle (2D)."""
    d = sig.shape[0]
    p = -np.trace(sig) / d
    s = sig + p * np.eye(d)
    q = math.sqrt(0.5 * np.sum(s * s)) if d == 2 else math.sqrt(1.5 * np.sum(s * s))
    return q / p if p > 0.0 else math.inf


class Adaptive(MicroModel):
    """An RVE that runs only once its Gauss point leaves the elastic range.

    While the strain accumulated since the RVE last ran stays below
    ``strain_threshold`` (Frobenius norm) and the trial stress ratio (see
    :func:`stress_ratio`) stays below ``ratio_threshold``, the point answers with the
    RVE's own contact tangent, ``sigma = sigma_c + C_e : deps``, at the cost of a
    matrix product. The first trial outside that range hands the accumulated strain
    to the RVE; once such a trial is committed the point runs the DEM from then on.

    With ``finite=True`` (finite kinematics) the increments accumulate as the map
    ``F`` the RVE owes, ``F = R U``; the thresholds apply to the rotation-free part
    ``U - I``, the elastic answer turns with the material,
    ``sigma = R (sigma_c + C_e : (U - I)) R^T`` with the tangent ``C_e`` turned by
    ``R`` too, and the first DEM call gets ``F - I``.
    """

    def __init__(self, dem_model, strain_threshold=1e-4, ratio_threshold=0.3,
                 finite=False):
        if not (strain_threshold > 0.0 and ratio_threshold > 0.0):
            raise ValueError("strain_threshold and ratio_threshold must be positive")
        self.finite = bool(finite)
        self.objective = self.finite
        self.dem = dem_model
        self.dim = dem_model.dim
        self.strain_threshold = float(strain_threshold)
        self.ratio_threshold = float(ratio_threshold)
        self.c_elastic = dem_model.elastic_tangent()
        self.active = False  # the DEM runs from now on (committed)
        # the elastic strain the RVE owes (finite: the increment map it owes)
        self.pending = np.eye(self.dim) if self.finite else np.zeros((self.dim, self.dim))
        self.stress = dem_model.stress.copy()
        self._trial_stress = self.stress
        self._trial_active = False
        self._trial_deps = np.zeros((self.dim, self.dim))
        self.cost = 0.0
        self.steps = 0

    @property
    def ran_dem(self):
        return self.active

    def trial(self, deps):
        if self.finite:
            return self._trial_finite(deps)
        if not self.active:
            total = self.pending + deps
            eps = 0.5 * (deps + deps.T)
            sig = self.stress + np.einsum("ijkl,kl->ij", self.c_elastic, eps)
            if (np.linalg.norm(total) < self.strain_threshold
                    and stress_ratio(sig) < self.ratio_threshold):
                self._trial_active = False
                self._trial_stress = sig
                self._trial_deps = np.array(deps, dtype=np.float64)
                self.cost, self.steps = 0.0, 0
                return sig, self.c_elastic
            deps = total
        self._trial_active = True
        sig, c = self.dem.trial(deps)
        self._trial_stress = sig
        self.cost, self.steps = self.dem.cost, self.dem.steps
        return sig, c

    def _trial_finite(self, deps):
        if not self.active:
            owed = _increment(deps, self.dim) @ self.pending
            r, u = polar(owed)
            stretch = u - np.eye(self.dim)
            sig = r @ (self.dem.stress + np.einsum("ijkl,kl->ij", self.c_elastic,
                                                   stretch)) @ r.T
            if (np.linalg.norm(stretch) < self.strain_threshold
                    and stress_ratio(sig) < self.ratio_threshold):
                self._trial_active = False
                self._trial_stress = sig
                self._trial_deps = owed
                self.cost, self.steps = 0.0, 0
                return sig, rotate4(self.c_elastic, r)
            deps = owed - np.eye(self.dim)
        self._trial_active = True
        sig, c = self.dem.trial(deps)
        self._trial_stress = sig
        self.cost, self.steps = self.dem.cost, self.dem.steps
        return sig, c

    def commit(self):
        if self._trial_active:
            self.dem.commit()
            self.active = True
            self.pending[:] = np.eye(self.dim) if self.finite else 0.0
        elif self.finite:  # the RVE has not moved; it owes the committed map
            self.pending = self._trial_deps.copy()
        else:  # the RVE has not moved; it owes the committed elastic strain
            self.pending += self._trial_deps
        self.stress = self._trial_stress

    def rollback(self):
        self.dem.rollback()
        self._trial_stress = self.stress
        self._trial_active = False

    def export(self):
        out = {"dem/" + k: v for k, v in self.dem.export().items()}
        out.update(pending=self.pending.copy(), active=np.array(self.active),
                   c_elastic=self.c_elastic.copy(), stress=np.array(self.stress))
        return out

    def load(self, state):
        self.dem.load({k[4:]: v for k, v in state.items() if k.startswith("dem/")})
        self.pending = np.array(state["pending"], dtype=np.float64)
        self.active = bool(state["active"])
        self.c_elastic = np.array(state["c_elastic"], dtype=np.float64)
        self.stress = np.array(state["stress"], dtype=np.float64)
        self._trial_stress = self.stress
        self._trial_active = False

    def measures(self):
        m = self.dem.measures()
        m["ran_dem"] = float(self.active)
        return m
