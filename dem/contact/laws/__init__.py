"""Contact laws: one file each, and the registry every other part of the package reads.

A law is a parameter object (a :class:`Law` subclass: :class:`LinearSpring`,
:class:`HertzMindlin`) and its compiled kernels, in one file of this package:

* ``force``: the force on the neighbour j of one contact, from the contact's summary
  (overlap, normal, relative velocity, effective radius and mass), the material pair's
  parameter row and the contact's history row (updated in place; the caller resets it
  when the contact opens);
* ``stiffness``: normal and tangential tangent stiffness [N/m], for the critical time
  step and the RVE's tangent operator;
* ``energy``: the elastic energy stored in the contact [J];
* ``normal_stiffness``: the normal stiffness inside the loops (rolling resistance
  scales with it).

:func:`register` adds a class to :data:`LAWS`; :mod:`.dispatch`, built once the
package's laws are registered, turns a law's ``code`` into its kernels inside compiled code;
the scene schema (:func:`contact_keys`), the file builders (:meth:`Law.from_table`), the
checkpoints (:func:`law_from_spec`) and the loops all read the registry. How to add a
law: ``docs/architecture.md``.

Tangential history is a time-dependent state: its rate is the tangential relative
velocity (:mod:`.tangential`, the spring both built-in laws use).
"""

from .base import (LAWS, Law, by_code, common_keys, law_class, law_from_spec, register,
                   unregister)
from . import dispatch
from .dispatch import contact_energy, contact_stiffness
from .hertz_mindlin import (HertzMindlin, energy_hertz_mindlin, law_hertz_mindlin,
                            stiffness_hertz_mindlin)
from .hertz_sjkr import HertzSJKR
from .linear import Elastic, LinearSpring, Viscoelastic, energy_linear, law_linear, stiffness_linear
from .tangential import N_HIST, tangential

# the compiled dispatch, one branch per law registered above
dispatch.build(LAWS.values())
apply_law = dispatch.apply_law
normal_stiffness = dispatch.normal_stiffness
row_size = dispatch.row_size
law_stiffness = dispatch.law_stiffness
law_energy = dispatch.law_energy

__all__ = ["LAWS", "N_HIST", "Elastic", "HertzMindlin", "HertzSJKR", "Law", "LinearSpring",
           "Viscoelastic", "apply_law", "by_code", "common_keys", "contact_energy", "contact_keys",
           "contact_stiffness", "energy_hertz_mindlin", "energy_linear", "law_class",
           "law_energy", "law_from_spec", "law_hertz_mindlin", "law_linear", "law_stiffness",
           "normal_stiffness", "register", "row_size", "stiffness_hertz_mindlin",
           "stiffness_linear", "tangential", "unregister"]


def contact_keys():
    """The keys of a ``[contact]`` table (:class:`dem.io.schema.Key` by name): ``law``
    with the registered names, each law's own keys (``only`` that law) and the keys
    every law shares. Rolling keys and ``pair`` are the files' to add."""
    from ...io.schema import REQUIRED, Key

    keys = {"law": Key("str", default=REQUIRED, choices=tuple(LAWS), doc="Contact law.")}
    for name, cls in LAWS.items():
        for key, spec in cls.keys().items():
            keys[key] = _shared(keys.get(key), spec, name, key)
    keys.update(common_keys())
    return keys


def _shared(old, spec, name, key):
    """``spec`` for law ``name`` alone, or ``old`` widened to it when another law has
    the same key with the same meaning."""
    import dataclasses

    if old is None:
        return dataclasses.replace(spec, only=(name,))
    if dataclasses.replace(old, only=()) != dataclasses.replace(spec, only=()):
        raise ValueError(f"contact law {name}: key {key} differs from another law's {key}")
    return dataclasses.replace(old, only=old.only + (name,))
