"""The laws' kernels as the compiled loops call them: by the law's ``code``.

:func:`build` writes each function below with one branch per registered law
(:func:`dem._jit.branch_on`), when ``dem/contact/laws/__init__.py`` has registered the
package's laws. The functions are inlined into the loops, which are compiled per scene
with the codes of its laws as constants, so the branch folds away and the loop holds
the law's own kernel; called with a code known only at run time (the observers'
batches, the RVE's measure), the branch is taken at run time. A code no built law has
gives NaN.

The signatures, for a contact of materials ``a``, ``b`` whose parameter rows are
``p[a, b, :]`` (no array view is made in the hot loop), with overlap ``ov`` > 0 [m], the
unit normal ``n`` from the home body i to the neighbour j, the velocity ``v`` of j
relative to i at the contact point [m/s], the effective radius ``r_eff`` [m] and mass
``m_eff`` [kg], the history rows ``hist`` with this contact's at ``k``, and the time
step ``dt`` [s] (0: evaluate without advancing the history):

* ``apply_law(code, ov, nx, ny, nz, vx, vy, vz, r_eff, m_eff, p, a, b, hist, k, dt)``:
  the force on j (i gets the opposite), three scalars (2D contacts pass ``z = 0``);
* ``normal_stiffness(code, ov, r_eff, p, a, b)``: the normal tangent stiffness [N/m];
* ``row_size(code)``: the length of the law's parameter row (the rolling parameters
  follow it);
* ``law_stiffness(code, ov, r_eff, row)``: normal and tangential tangent stiffness
  [N/m] from one parameter row; ``law_energy(code, ov, r_eff, row, hist, k)``: the
  elastic energy [J];
* ``contact_stiffness``, ``contact_energy``: the same over many contacts.

Why generated branches and not numba's ``overload`` on a literal code: an overload
inlined into kernels that are themselves inlined lost array writes in the mesh-wall
contacts (the variable-name clashes of numba's typed inlining), and compiled without
inlining it made the loops' cold compile twice as long. A fixed chain of spare
branches would cost compile time too (numba types every branch of an inlined
function). A law registered after the build is refused by the contact model
(:func:`check_built`).

Inlined or called: a law whose ``force`` kernel is compiled with ``inline=True``
(:mod:`.linear`, :mod:`.hertz_mindlin`) is inlined into every loop, but so is it into
the loops of every other law's scenes, where numba types and lowers it before LLVM
drops it: a third inlined law cost the cold compile of every sphere loop about 2 s
(6 %). A force kernel compiled without ``inline`` (:mod:`.hertz_sjkr`) is compiled
once and called: the other laws' loops compile no slower, and its own scenes run about
10 % slower for the call per contact (``docs/performance.md``, "A third contact law").
"""

import math

from ..._jit import branch_on, kernel

_FORCE = ("ov", "nx", "ny", "nz", "vx", "vy", "vz", "r_eff", "m_eff", "p", "a", "b", "hist",
          "k", "dt")


@kernel(inline=True)
def _no_force(ov, nx, ny, nz, vx, vy, vz, r_eff, m_eff, p, a, b, hist, k, dt):
    return math.nan, math.nan, math.nan


@kernel(inline=True)
def _no_normal(ov, r_eff, p, a, b):
    return math.nan


@kernel(inline=True)
def _no_stiffness(ov, r_eff, row):
    return math.nan, math.nan


@kernel(inline=True)
def _no_energy(ov, r_eff, row, hist, k):
    return math.nan


@kernel(inline=True)
def _no_row():
    return 0


#: the codes the functions below were built for
BUILT = ()
#: written by :func:`build`
apply_law = normal_stiffness = row_size = law_stiffness = law_energy = None


def build(laws):
    """Write the dispatch functions for the law classes ``laws`` (once)."""
    global BUILT, apply_law, normal_stiffness, row_size, law_stiffness, law_energy
    if BUILT:
        raise RuntimeError("the contact-law dispatch is built once, when dem.contact.laws "
                           "is imported")
    by_code = {cls.code: cls for cls in laws}

    def kernels(attr):
        return {c: getattr(cls, attr) for c, cls in by_code.items()}

    apply_law = branch_on("apply_law", _FORCE, kernels("force"), _no_force,
                          "Force on j from the law with this ``code`` (module docstring).")
    normal_stiffness = branch_on(
        "normal_stiffness", ("ov", "r_eff", "p", "a", "b"), kernels("normal_stiffness"),
        _no_normal, "The law's normal tangent stiffness [N/m] of a contact.")
    row_size = branch_on("row_size", (), {c: _constant(cls.n_params)
                                          for c, cls in by_code.items()}, _no_row,
                         "Length of the law's own parameter row (rolling's follow it).")
    law_stiffness = branch_on(
        "law_stiffness", ("ov", "r_eff", "row"), kernels("stiffness"), _no_stiffness,
        "Normal and tangential tangent stiffness [N/m] from a parameter ``row``.")
    law_energy = branch_on(
        "law_energy", ("ov", "r_eff", "row", "hist", "k"), kernels("energy"), _no_energy,
        "Elastic energy [J] of a contact from its parameter ``row``.")
    BUILT = tuple(sorted(by_code))


def _constant(value):
    value = int(value)

    @kernel(inline=True, cache=False)
    def constant():
        return value
    return constant


def check_built(law):
    """Refuse a law whose code the dispatch was not built for."""
    if law.code not in BUILT:
        raise ValueError(f"contact law {law.name!r} was registered after dem.contact.laws "
                         "was loaded, so the compiled loops cannot call it: give it a "
                         "file in dem/contact/laws/ and import it in its __init__.py")


@kernel
def contact_stiffness(code, ov, r_eff, p, ma, mb, kn_out, kt_out):
    """Tangent stiffnesses [N/m] of many contacts of law ``code`` (observers, not steps)."""
    for c in range(ov.shape[0]):
        kn, kt = law_stiffness(code, ov[c], r_eff[c], p[ma[c], mb[c]])
        kn_out[c] = kn
        kt_out[c] = kt


@kernel
def contact_energy(code, ov, r_eff, p, ma, mb, hist, rows):
    """Elastic energy [J] of the contacts ``rows`` (with ``ov[c]`` > 0) of law ``code``."""
    e = 0.0
    for c in range(rows.shape[0]):
        k = rows[c]
        e += law_energy(code, ov[k], r_eff[k], p[ma[k], mb[k]], hist, k)
    return e
