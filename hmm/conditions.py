"""Boundary conditions and loads of a macro problem, written as Python objects.

A problem file's ``[[dirichlet]]``, ``[[platen]]``, ``[[periodic]]``, ``[[pressure]]``,
``[[traction]]`` and ``[body_force]`` become the objects of this module
(:mod:`hmm.problem`), and a Python user writes them directly::

    supports = hmm.supports(macro, [hmm.Dirichlet("bottom", "y"),
                                    hmm.Dirichlet("top", "y", value=-1e-4)])
    f_const, f_ramp, loads = hmm.external_forces(macro, [hmm.Pressure("right", 1e5)])
    solver = hmm.Solver(macro, farm, supports, f_const, f_ramp, loads=loads)

Prescribed displacements grow linearly with the load factor (0 to 1 over the
schedule): a :class:`Dirichlet` ``value`` [m], an affine one ``u = G (x - origin)``
(``gradient`` G [-]) and the jumps ``G L`` of :class:`Periodic` pairs (``L`` [m] the
period) are reached at load factor 1. Components are ``"x"``, ``"y"``, ``"z"`` or
0, 1, 2. Every error is a :class:`ValueError` whose message is one line naming the
condition and the cause.
"""

from dataclasses import dataclass

import numpy as np

from .coupling import Supports
from .periodic import PairError, periodic_ties

#: the displacement components by name
COMPONENTS = ("x", "y", "z")


def component_index(component, dim):
    """0..dim-1 for ``"x"``/``"y"``/``"z"`` or an integer; ValueError otherwise.

    Examples
    --------
    >>> component_index("y", 2), component_index(2, 3)
    (1, 2)
    """
    c = COMPONENTS.index(component) if component in COMPONENTS else component
    if isinstance(c, (bool, str)) or not isinstance(c, (int, np.integer)) \
            or not 0 <= c < dim:
        raise ValueError(f"component {component!r} does not exist in {dim}D "
                         f"(x, y{', z' if dim == 3 else ''} or 0..{dim - 1})")
    return int(c)


def gradient_tensor(gradient, dim):
    """A displacement gradient as a (dim, dim) float array: a number ``g`` means
    ``g I`` (a uniform dilation); ValueError on a wrong shape or a non-finite entry.

    Examples
    --------
    >>> gradient_tensor(0.01, 2).tolist()
    [[0.01, 0.0], [0.0, 0.01]]
    """
    g = np.asarray(gradient, dtype=np.float64)
    if g.ndim == 0:
        g = float(g) * np.eye(dim)
    if g.shape != (dim, dim):
        raise ValueError(f"gradient must be a number or {dim} x {dim}, got shape "
                         f"{g.shape}")
    if not np.all(np.isfinite(g)):
        raise ValueError("gradient must be finite")
    return g


@dataclass(frozen=True)
class Dirichlet:
    """A prescribed displacement on a named ``boundary`` or at a mesh vertex ``point``.

    Parameters
    ----------
    boundary : str, optional
        A named boundary of the mesh (this or ``point``).
    component : str or int, optional
        The component held; None with a ``gradient``: every component.
    value : float
        [m] at load factor 1 (a uniform displacement of the component).
    gradient : (d, d) array_like or float, optional
        [-] an affine displacement ``u = G (x - origin)`` at load factor 1 instead of
        ``value`` (``x`` the initial position of each node; a number ``g`` is
        ``g I``).
    origin : (d,) array_like, optional
        [m] the point that the affine displacement leaves in place (default 0).
    point : (d,) array_like, optional
        [m] a vertex of the mesh (a point support), instead of ``boundary``.
    """

    boundary: str = None
    component: object = None
    value: float = 0.0
    gradient: object = None
    origin: object = None
    point: object = None

    @property
    def name(self):
        """What the reactions call this support: the boundary, or ``point (x, y)``."""
        if self.boundary is not None:
            return self.boundary
        return "point (" + ", ".join(f"{x:g}" for x in self.point) + ")"

    def conditions(self, macro):
        """``[(name, component, dofs, values)]``: the degrees of freedom held and their
        values [m] at load factor 1, one entry per component."""
        d = macro.dim
        if (self.boundary is None) == (self.point is None):
            raise ValueError("needs a boundary or a point (one of them)")
        if self.gradient is None:
            if self.component is None:
                raise ValueError("needs a component (or a gradient)")
            if self.origin is not None:
                raise ValueError("origin applies with a gradient only")
        elif self.value != 0.0:
            raise ValueError("takes a value or a gradient, not both")
        comps = range(d) if self.component is None else \
            [component_index(self.component, d)]
        if self.boundary is not None:
            known = macro.mesh.boundaries or {}
            if self.boundary not in known:
                raise ValueError(f"boundary \"{self.boundary}\" is not a boundary of the "
                                 f"mesh (known: {', '.join(sorted(known)) or 'none'})")
            dofs = [macro.dofs(self.boundary, c) for c in comps]
        else:
            v = vertex_at(macro.mesh, self.point)
            if v is None:
                raise ValueError(f"point = {list(self.point)} is not a vertex of the mesh")
            dofs = [np.asarray(macro.basis.nodal_dofs[c, [v]]) for c in comps]
        if self.gradient is None:
            return [(self.name, c, k, float(self.value)) for c, k in zip(comps, dofs, strict=True)]
        g = gradient_tensor(self.gradient, d)
        origin = np.zeros(d) if self.origin is None else np.asarray(self.origin, float)
        if origin.shape != (d,):
            raise ValueError(f"origin must have {d} coordinates, got {list(origin)}")
        out = []
        for c, k in zip(comps, dofs, strict=True):
            x = macro.basis.doflocs[:, k].T - origin  # (n, d): where each dof sits
            out.append((self.name, c, k, x @ g[c]))
            if not np.all(np.isfinite(out[-1][3])):
                raise ValueError("gradient gives displacements beyond floating point")
        return out


@dataclass(frozen=True)
class Platen:
    """A rigid frictionless platen: ``component`` of ``boundary`` moves as one unknown,
    pushed by the loads on the boundary."""

    boundary: str
    component: object


@dataclass(frozen=True)
class Periodic:
    """Two opposite boundaries tied: ``u(x + L) = u(x) + G L`` for every node ``x`` of
    ``boundary`` and its image ``x + L`` on ``image`` (``L`` [m] the shift between
    them, ``G`` the average displacement gradient given to :func:`supports`)."""

    boundary: str
    image: str


class ConditionError(ValueError):
    """A condition that does not fit the mesh: ``kind`` (``"dirichlet"``,
    ``"platen"``, ``"periodic"``), ``index`` (0-based; None: the conditions of that
    kind together) and the one-line ``reason``."""

    def __init__(self, kind, index, reason):
        self.kind, self.index, self.reason = kind, index, reason
        where = kind if index is None else f"{kind} #{index + 1}"
        super().__init__(f"{where}: {reason}")


def supports(macro, dirichlet=(), platens=(), periodic=(), gradient=None):
    """The :class:`~hmm.coupling.Supports` of a macro problem.

    Parameters
    ----------
    macro : Macro
    dirichlet : sequence of Dirichlet
        In order: a degree of freedom named twice (a corner of two supported edges)
        keeps the first value and belongs to the first support's reaction.
    platens : sequence of Platen
    periodic : sequence of Periodic
        Pairs of opposite boundaries; a node on several pairs (a corner) is tied to
        all its images. Hold one node (a :class:`Dirichlet` at a ``point``) against
        rigid translation.
    gradient : (d, d) array_like or float, optional
        [-] the average displacement gradient ``G`` of the periodic pairs at load
        factor 1 (default 0: periodic fluctuations under the other loads).

    Raises
    ------
    ConditionError
        Naming the condition: an unknown boundary, a point off the mesh, a platen on
        held degrees of freedom, boundaries that are not images of each other.

    Examples
    --------
    >>> from hmm.macro import Macro, structured_mesh
    >>> macro = Macro(structured_mesh("quad1", [1.0, 1.0], [2, 2]))
    >>> s = supports(macro, [Dirichlet("left", gradient=[[0.0, 0.1], [0.0, 0.0]])])
    >>> sorted(s.held), float(s.values.max())   # u_x = 0.1 y on the left edge, at y = 1
    (['left'], 0.1)
    """
    conditions = []
    for i, c in enumerate(dirichlet):
        try:
            conditions += c.conditions(macro)
        except ValueError as err:
            raise ConditionError("dirichlet", i, str(err)) from None
    curve = tuple(dict.fromkeys(c.boundary for c in dirichlet if c.boundary is not None))
    sup = Supports.from_conditions(conditions, curve)
    ties = []
    for i, p in enumerate(platens):
        try:
            k = _boundary_dofs(macro, p.boundary, component_index(p.component, macro.dim))
        except ValueError as err:
            raise ConditionError("platen", i, str(err)) from None
        if np.intersect1d(k, sup.dofs).size or any(np.intersect1d(k, t).size
                                                   for t in ties):
            raise ConditionError("platen", i, f"boundary \"{p.boundary}\" "
                                 f"{COMPONENTS[component_index(p.component, 3)]} is "
                                 f"also held by a [[dirichlet]] or another platen")
        ties.append(np.unique(k))  # sorted: its first dof stands for the platen
    values = [np.zeros(t.size) for t in ties]
    if periodic:
        try:
            g = gradient_tensor(0.0 if gradient is None else gradient, macro.dim)
            groups, jumps = periodic_ties(macro, periodic, g, sup.dofs, ties)
        except PairError as err:
            raise ConditionError("periodic", err.index, err.reason) from None
        except ValueError as err:
            raise ConditionError("periodic", None, str(err)) from None
        ties += groups
        values += jumps
    elif gradient is not None:
        raise ValueError("gradient applies to periodic pairs: none given")
    sup.ties = tuple(ties)
    sup.tie_values = tuple(values) if periodic else ()
    return sup


def free_rigid_motions(macro, sup, tol=1e-8):
    """The rigid-body motions the supports ``sup`` leave free, as words.

    A rigid motion (a translation, or a rotation about any axis) that vanishes on every
    prescribed degree of freedom and moves every group of ``sup.ties`` as one costs no
    energy: the tangent is singular and no load step converges. The motions are the
    null space of the rigid modes restricted to those constraints (so a rotation about
    an axis through any point counts); each is named by its largest part. An empty
    list: the supports hold the body.

    >>> from hmm.macro import Macro, structured_mesh
    >>> macro = Macro(structured_mesh("quad1", [1.0, 1.0], [2, 2]))
    >>> free_rigid_motions(macro, supports(macro, [Dirichlet("bottom", "y")]))
    ['a translation along x']
    """
    d, basis = macro.dim, macro.basis
    x = basis.doflocs
    comp = np.zeros(basis.N, np.int64)
    every = basis.get_dofs(elements=True)
    for c in range(d):
        comp[every.all(f"u^{c + 1}")] = c
    size = max(float(np.ptp(x, axis=1).max()), 1e-300)
    rel = (x - x.mean(axis=1, keepdims=True)) / size
    modes, names = [], []
    for c in range(d):
        modes.append((comp == c).astype(np.float64))
        names.append(f"a translation along {'xyz'[c]}")
    for axis in ((2,) if d == 2 else (0, 1, 2)):
        i, j = [a for a in range(3) if a != axis][:2] if d == 3 else (0, 1)
        r = np.zeros(basis.N)  # e_axis x (x - centre), scaled by the size
        r[comp == i] = -rel[j, comp == i]
        r[comp == j] = rel[i, comp == j]
        modes.append(r)
        names.append(f"a rotation about an axis along {'xyz'[axis]}")
    m = np.array(modes).T  # (N, n_modes)
    rows = [m[sup.dofs]] + [m[t[1:]] - m[t[0]] for t in sup.ties if len(t) > 1]
    a = np.concatenate(rows) if rows else np.zeros((0, m.shape[1]))
    s = np.linalg.svd(a, compute_uv=False) if a.size else np.zeros(0)
    n_free = m.shape[1] - int(np.count_nonzero(s > tol * np.sqrt(basis.N)))
    if n_free <= 0:
        return []
    null = np.linalg.svd(a)[2][m.shape[1] - n_free:] if a.size else np.eye(m.shape[1])
    return [names[int(np.argmax(np.abs(v)))] for v in null]


def _boundary_dofs(macro, boundary, component):
    known = macro.mesh.boundaries or {}
    if boundary not in known:
        raise ValueError(f"boundary \"{boundary}\" is not a boundary of the mesh "
                         f"(known: {', '.join(sorted(known)) or 'none'})")
    return macro.dofs(boundary, component)


def vertex_at(mesh, point):
    """Index of the mesh vertex at ``point`` [m] (within 1e-9 of the mesh size), or
    None."""
    dist = np.linalg.norm(mesh.p.T - np.asarray(point, dtype=np.float64), axis=1)
    v = int(np.argmin(dist))
    return v if dist[v] <= 1e-9 * float(np.ptp(mesh.p, axis=1).max()) else None


def cut_boundary(mesh, name, of, lo, hi):
    """``mesh`` with a new named boundary ``name``: the facets of boundary ``of`` whose
    midpoints lie in the box ``[lo, hi]`` [m] (a footing on the top face, say).

    Examples
    --------
    >>> from hmm.macro import structured_mesh
    >>> m = cut_boundary(structured_mesh("quad1", [1.0, 1.0], [4, 4]), "footing",
    ...                  "top", [0.0, 1.0], [0.5, 1.0])
    >>> len(m.boundaries["footing"])
    2
    """
    known = mesh.boundaries or {}
    if of not in known:
        raise ValueError(f"of = \"{of}\" is not a boundary of the mesh (known: "
                         f"{', '.join(sorted(known)) or 'none'})")
    if name in known:
        raise ValueError(f"name = \"{name}\" is taken")
    facets = np.asarray(known[of])
    mid = mesh.p[:, mesh.facets[:, facets]].mean(axis=1).T
    tol = 1e-9 * float(np.ptp(mesh.p, axis=1).max())
    inside = np.all((mid >= np.asarray(lo, dtype=np.float64) - tol)
                    & (mid <= np.asarray(hi, dtype=np.float64) + tol), axis=1)
    if not inside.any():
        raise ValueError(f"\"{name}\": no facet of \"{of}\" has its midpoint in [lo, hi]")
    return mesh.with_boundaries({name: facets[inside]})


# --------------------------------------------------------------------------- loads
@dataclass(frozen=True)
class Pressure:
    """A normal pressure [Pa] (compression positive) on ``boundary``: present from the
    start (``ramp`` false: it balances the micro models' initial stress) or growing
    with the load factor; under finite kinematics normal to the deformed boundary
    (``follower``) or a dead load on the initial one."""

    boundary: str
    value: float
    ramp: bool = False
    follower: bool = True


@dataclass(frozen=True)
class Traction:
    """A traction vector (d,) [Pa] on ``boundary``, ramped; under finite kinematics
    per unit ``"reference"`` (initial) or ``"current"`` area."""

    boundary: str
    value: tuple
    per: str = "reference"


@dataclass(frozen=True)
class BodyForce:
    """A body force density (d,) [N/m^3], ramped; under finite kinematics per unit
    ``"reference"`` volume (gravity: rho_0 g) or ``"current"`` volume."""

    value: tuple
    per: str = "reference"


def external_forces(macro, loads):
    """``(f_const, f_ramp, config_loads)`` of :class:`Pressure`, :class:`Traction` and
    :class:`BodyForce` terms: the constant and the ramped (at load factor 1) nodal
    forces (n_dofs,) [N] of the dead loads, and the configuration-dependent loads of
    finite kinematics (:mod:`hmm.loads`), the three arguments of
    :class:`~hmm.coupling.Solver` that describe the loading."""
    from .loads import CurrentBodyForce, CurrentTraction, FollowerPressure

    f_const = np.zeros(macro.n_dofs)
    f_ramp = np.zeros(macro.n_dofs)
    config = []
    for load in loads:
        if isinstance(load, Pressure):
            if macro.finite and load.follower:
                config.append(FollowerPressure(load.boundary, float(load.value), load.ramp))
                continue
            f = macro.pressure_force(load.boundary, load.value)
            if load.ramp:
                f_ramp += f
            else:
                f_const += f
        elif isinstance(load, Traction):
            if macro.finite and load.per == "current":
                config.append(CurrentTraction(load.boundary, tuple(load.value)))
            else:
                f_ramp += macro.traction_force(load.boundary, load.value)
        elif isinstance(load, BodyForce):
            if not any(load.value):
                continue
            if macro.finite and load.per == "current":
                config.append(CurrentBodyForce(tuple(load.value)))
            else:
                f_ramp += macro.body_force(load.value)
        else:
            raise TypeError(f"a load must be a Pressure, Traction or BodyForce, got "
                            f"{type(load).__name__}")
    return f_const, f_ramp, tuple(config)
