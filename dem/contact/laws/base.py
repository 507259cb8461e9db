"""The base of every contact law, and the registry the rest of the package reads.

A law is one class in one file of this package (:mod:`.linear`,
:mod:`.hertz_mindlin`), decorated with :func:`register`. The class states everything
the engine needs of it:

* ``name``: what scene, RVE and problem files call it (``law = "linear"``);
* ``code``: its number inside the compiled loops (a compile-time constant: a scene
  compiles only the laws it uses, :mod:`.dispatch`);
* ``n_params``: the length of its parameter row (:meth:`Law.row`), the rolling
  parameters follow it;
* ``n_hist``: the columns of a contact's history row it owns, from column 0 (any
  number; rolling resistance adds its own after them);
* its compiled kernels: ``force``, ``stiffness``, ``energy`` and
  ``normal_stiffness`` (signatures in :mod:`.dispatch`);
* :meth:`Law.keys`: its keys of a ``[contact]`` table, with units, defaults and
  ranges; :meth:`Law.wall_keys`: those a wall may set for its own material;
  :meth:`Law.arguments`: its constructor arguments from such a table.

Every law shares the keys of :func:`common_keys` (friction, restitution,
``limit_damping``; rolling resistance is in :data:`dem.io.materials.ROLLING_KEYS`).
The scene schema, the builders of scene and RVE files, the loop factories and the
homogenisation measures all read :data:`LAWS`: adding a law is adding a file here
(and importing it in ``__init__.py``), never editing those.
"""

import math

import numpy as np

from ..rolling import as_rolling

#: the registered law classes by name, in the order of their codes
LAWS = {}


def register(cls):
    """Class decorator: add a :class:`Law` subclass to :data:`LAWS`.

    Checks what the compiled loops rely on: a new name, a ``code`` of its own (a
    class constant: compiled loops are cached by it), a positive parameter row and
    every kernel.
    """
    if not (isinstance(cls.name, str) and cls.name.isidentifier()):
        raise ValueError(f"{cls.__name__}: name must be an identifier, got {cls.name!r}")
    if cls.name in LAWS:
        raise ValueError(f"a contact law named {cls.name!r} is registered already")
    taken = {other.code: other.__name__ for other in LAWS.values()}
    if not (isinstance(cls.code, int) and cls.code >= 0) or cls.code in taken:
        raise ValueError(f"{cls.__name__}: code must be an integer >= 0 that no other law "
                         f"has (taken: {taken}), got {cls.code!r}")
    if not (int(cls.n_params) > 0 and int(cls.n_hist) >= 0):
        raise ValueError(f"{cls.__name__}: n_params must be > 0 and n_hist >= 0")
    for kernel in ("force", "stiffness", "energy", "normal_stiffness"):
        if getattr(cls, kernel) is None:
            raise ValueError(f"{cls.__name__}: no {kernel} kernel")
    LAWS[cls.name] = cls
    ordered = sorted(LAWS.values(), key=lambda law: law.code)
    LAWS.clear()
    LAWS.update((law.name, law) for law in ordered)
    return cls


def unregister(name):
    """Take the law ``name`` out of the registry."""
    return LAWS.pop(name)


def law_class(name):
    """The registered law class called ``name`` (a file's ``law = ...``)."""
    if name not in LAWS:
        raise ValueError(f"unknown contact law {name!r}; known: {', '.join(LAWS)}")
    return LAWS[name]


def by_code(code):
    """The registered law class with this ``code``."""
    for cls in LAWS.values():
        if cls.code == code:
            return cls
    raise ValueError(f"no contact law has code {code}")


def law_from_spec(spec):
    """Rebuild a law from :meth:`Law.spec` data; unknown names or arguments raise."""
    spec = dict(spec)
    name = spec.pop("law", None)
    kinds = {cls.__name__: cls for cls in LAWS.values()}
    if name not in kinds:
        raise ValueError(f"unknown contact law {name!r}; known: {', '.join(kinds)}")
    try:
        return kinds[name](**spec)
    except TypeError as err:
        raise ValueError(f"contact law {name}: {err}") from None


def common_keys():
    """The ``[contact]`` keys every law takes (a file's schema), by name."""
    from ...io.schema import NONNEGATIVE, REQUIRED, UNIT_OPEN_CLOSED, Key

    return {
        "mu": Key("float", default=REQUIRED, range=NONNEGATIVE,
                  doc="Coulomb friction coefficient."),
        "restitution": Key("float", default=1.0, range=UNIT_OPEN_CLOSED,
                           doc="Normal coefficient of restitution."),
        "limit_damping": Key("bool", default=False,
                             doc="Clip the normal force at zero (the dashpot never pulls), "
                                 "the damping remapped so that a collision still rebounds "
                                 "with the restitution (LAMMPS' limit_damping)."),
    }


def check_number(name, value, lo=0.0, strict=False):
    """``value`` as a float, finite and ``>= lo`` (``> lo`` if ``strict``), or a
    ValueError naming it."""
    value = float(value)
    ok = math.isfinite(value) and (value > lo if strict else value >= lo)
    if not ok:
        rel = ">" if strict else ">="
        raise ValueError(f"{name} must be finite and {rel} {lo}, got {value}")
    return value


class Law:
    """Base of the law parameter objects: names its kernels and its parameter row."""

    #: what files call the law (``[contact] law = ...``)
    name = None
    #: selects the law's kernels inside the compiled loops
    code = -1
    #: length of :meth:`row`
    n_params = 0
    #: history columns the law owns (its tangential spring, ...)
    n_hist = 3
    force = None
    stiffness = None
    energy = None
    normal_stiffness = None
    #: rolling resistance (:class:`~dem.contact.rolling.Rolling`), or None
    rolling = None

    def _set_rolling(self, rolling):
        self.rolling = as_rolling(rolling)
        if self.rolling is not None:
            self._args["rolling"] = self.rolling.spec()

    def row(self):
        """The pair-parameter row the kernels read (float64 array of ``n_params``)."""
        raise NotImplementedError

    def full_row(self, rolling):
        """:meth:`row`, followed by the rolling parameters when ``rolling`` (zeros for a
        law without rolling resistance in a scene where others have it)."""
        row = np.asarray(self.row(), np.float64)
        if row.shape != (self.n_params,):
            raise TypeError(f"{type(self).__name__}.row() gives {row.size} numbers, but the "
                            f"class states n_params = {self.n_params}")
        if not rolling:
            return row
        extra = self.rolling.row() if self.rolling is not None else [0.0] * 5
        return np.concatenate([row, extra])

    def critical_stiffness(self, r_ref):
        """Largest normal stiffness [N/m] a contact of reference radius ``r_ref`` reaches."""
        raise NotImplementedError

    def damping_ratios(self, m_eff, rot):
        """Damping ratios [-] of a contact's normal and tangential modes, ``(zeta_n,
        zeta_t)``.

        ``m_eff`` [kg] is the pair's effective mass, ``rot`` the rotational coupling of
        the tangential mode (``1 + m r^2 / I``): it scales that mode's stiffness and
        dashpot alike, so its ratio by ``sqrt(rot)``.
        """
        raise NotImplementedError

    def damping_ratio(self, m_eff, rot):
        """Largest damping ratio [-] of a contact's normal and tangential modes."""
        return max(self.damping_ratios(m_eff, rot))

    def spec(self):
        """The law as plain data: ``{"law": class name, **constructor arguments}``;
        :func:`law_from_spec` rebuilds it (files store laws this way, never as code)."""
        return {"law": type(self).__name__, **self._args}

    def with_friction(self, mu):
        """A copy of the law with friction coefficient ``mu``."""
        return law_from_spec({**self.spec(), "mu": float(mu)})

    # ------------------------------------------------------------------ files
    @classmethod
    def keys(cls):
        """The law's own keys of a ``[contact]`` table (:class:`dem.io.schema.Key` by
        name), beside :func:`common_keys`."""
        raise NotImplementedError

    @classmethod
    def wall_keys(cls):
        """The keys of :meth:`keys` that a wall (``[[walls]]``, ``[[meshes]]``) may set
        for its own material, with their meaning for a wall."""
        raise NotImplementedError

    @classmethod
    def arguments(cls, table, wall):
        """The constructor arguments (but ``rolling`` and ``limit_damping``) from a
        validated ``[contact]`` table, with a wall's own keys ``wall`` (a dict, empty
        for particle pairs) replacing its values."""
        raise NotImplementedError

    @classmethod
    def from_table(cls, table, wall=None, rolling=None):
        """The law of a validated ``[contact]`` table (and a wall's own keys): its
        :meth:`arguments`, ``limit_damping`` and the ``rolling`` resistance given."""
        args = cls.arguments(table, {k: v for k, v in (wall or {}).items() if v is not None})
        if table.get("limit_damping") or (wall or {}).get("limit_damping"):
            args["limit_damping"] = True
        if rolling is not None:
            args["rolling"] = rolling
        return cls(**args)
