"""Multiscale (FEMxDEM) coupling: a scikit-fem macro problem with DEM micro models.

The pieces a scikit-fem user composes (SI units throughout; ``docs/python_api.md``
builds and runs a problem with them):

mesh and boundaries
    :func:`structured_mesh`, :func:`tensor_mesh` (graded), or any skfem mesh with
    named boundaries (e.g. ``MeshQuad.init_tensor(x, y).with_defaults()``),
    :func:`cut_boundary`,
    :func:`read_mesh`, and :class:`Macro`: a vector basis on the mesh, its Gauss
    points and the forms of a Newton iteration, in ``"small"`` or ``"finite"``
    kinematics.
conditions and loads
    :class:`Dirichlet` (a value, or an affine ``u = G x``), :class:`Platen`,
    :class:`Periodic` pairs, gathered by :func:`supports`; :class:`Pressure`,
    :class:`Traction`, :class:`BodyForce`, turned into force vectors by
    :func:`external_forces`.
micro models
    :class:`LinearElastic`, :class:`Hyperbolic`, :class:`Hypoelastic`,
    :class:`NeoHookean` (analytic), :class:`DEMMicroModel` (a periodic DEM RVE from
    ``dem.rve``; :func:`clone_rve` copies one packing per Gauss point) and
    :class:`Adaptive` (DEM only outside the elastic range), all behind
    :class:`MicroModel`.
farm
    :class:`SerialFarm`, :class:`MPIFarm`, or :func:`make_farm` (MPI when run under
    ``mpiexec``).
solver
    :class:`Solver` (``advance(dt)``: one load increment, Newton with step cutting),
    :class:`SolverSettings`, :class:`SolverError`.
output
    :class:`Output`: ``fields.h5`` + ``fields.xdmf`` (ParaView, meshio) and plots;
    :func:`read_fields` reads a run's ``fields.h5`` back as arrays with units
    (:class:`Fields`).
problem files
    :func:`load_problem`, :func:`validate_problem`, :func:`run_problem` (what
    ``hmm run`` does).

Names load on first use, so ``import hmm`` costs almost nothing; the submodules
(``hmm.macro``, ``hmm.micro``, ``hmm.farm``, ``hmm.coupling``, ``hmm.conditions``,
``hmm.periodic``, ``hmm.problem``, ``hmm.run``, ``hmm.io``, ``hmm.reader``,
``hmm.checkpoint``,
``hmm.experiment``, ``hmm.batch``, ``hmm.cli``) hold the rest.
"""

import importlib

#: public name -> the submodule that defines it
_WHERE = {
    "structured_mesh": "macro", "tensor_mesh": "macro", "Macro": "macro",
    "ELEMENTS": "macro",
    "cut_boundary": "conditions", "Dirichlet": "conditions", "Platen": "conditions",
    "Periodic": "conditions", "supports": "conditions", "Pressure": "conditions",
    "Traction": "conditions", "BodyForce": "conditions", "external_forces": "conditions",
    "ConditionError": "conditions",
    "Supports": "coupling", "Solver": "coupling", "SolverSettings": "coupling",
    "SolverError": "coupling",
    "MicroModel": "micro", "LinearElastic": "micro", "Hyperbolic": "micro",
    "Hypoelastic": "micro", "NeoHookean": "micro", "DEMMicroModel": "micro",
    "Adaptive": "micro",
    "SerialFarm": "farm", "MPIFarm": "farm", "make_farm": "farm",
    "Output": "io", "read_fields": "reader", "Fields": "reader",
    "read_mesh": "problem_build", "clone_rve": "problem_build", "load_problem": "problem",
    "validate_problem": "problem",
    "run_problem": "run",
}

__all__ = sorted(_WHERE)


def __getattr__(name):
    if name in _WHERE:
        value = getattr(importlib.import_module(f".{_WHERE[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'hmm' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_WHERE))
