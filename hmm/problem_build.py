"""What a validated problem file (:func:`hmm.problem.validate_problem`) builds: the
macro mesh and its conditions, the pore-pressure field and time schedule of a saturated
problem, and the micro models of the Gauss points in a farm.

Every problem the file's values cannot satisfy (a boundary the mesh lacks, an unreadable
mesh or packing file) is a one-line :class:`~dem.io.scene.SceneError` naming the file and
the key.
"""

import math
from pathlib import Path

import numpy as np

from dem.io.schema import SceneError
from dem.limits import PARTICLES, LimitError

from .conditions import (
    BodyForce,
    ConditionError,
    Dirichlet,
    Periodic,
    Platen,
    Pressure,
    Traction,
    cut_boundary,
    external_forces,
    free_rigid_motions,
    supports,
    vertex_at,
)
from .problem_schema import MESH_ELEMENTS

__all__ = ["build_farm", "build_loads", "build_macro", "build_models", "build_porous",
           "clone_rve", "initial_stress_check", "model_factory", "read_mesh", "spot_of"]


def _mesh(problem):
    """The mesh of ``[mesh]``: structured, graded (element edges per axis) or read."""
    from .macro import ELEMENTS, structured_mesh, tensor_mesh

    m = problem["mesh"]
    if m["x"] is not None:
        return tensor_mesh(m["element"], [m[a] for a in "xyz"[:m["dim"]]])
    if m["file"] is None:
        return structured_mesh(m["element"], m["size"], [int(c) for c in m["cells"]])
    src = problem["source"]
    mesh = read_mesh(m["file"], f"{src}: [mesh]")
    if not isinstance(mesh, ELEMENTS[m["element"]][0]):
        raise SceneError(f"{src}: [mesh] file holds a {type(mesh).__name__}, "
                         f"element \"{m['element']}\" needs a "
                         f"{ELEMENTS[m['element']][0].__name__}")
    return mesh


def build_macro(problem):
    """The :class:`~hmm.macro.Macro` of a validated problem; boundary names checked."""
    from .macro import Macro

    src = problem["source"]
    m = problem["mesh"]
    mesh = _mesh(problem)
    if mesh.t.shape[1] == 0:
        raise SceneError(f"{src}: [mesh] has no elements")
    try:
        if m["file"] is not None:
            MESH_ELEMENTS.check(mesh.t.shape[1], f"the elements of {m['file']}")
    except LimitError as exc:
        raise SceneError(f"{src}: [mesh] {exc}") from None
    mesh = _cut_boundaries(problem, mesh)
    known = set(mesh.boundaries or {})
    for kind in ("dirichlet", "pressure", "traction", "drainage", "platen", "periodic"):
        for i, c in enumerate(problem[kind]):
            if c.get("point") is not None:
                if vertex_at(mesh, c["point"]) is None:
                    raise SceneError(f"{src}: [[{kind}]] #{i + 1} point = "
                                     f"{list(c['point'])} is not a vertex of the mesh")
                continue
            if c["boundary"] not in known:
                raise SceneError(f"{src}: [[{kind}]] #{i + 1} boundary "
                                 f"\"{c['boundary']}\" is not a boundary of the mesh "
                                 f"(known: {', '.join(sorted(known)) or 'none'})")
    for i, c in enumerate(problem["periodic"]):
        if c["image"] not in known:
            raise SceneError(f"{src}: [[periodic]] #{i + 1} image \"{c['image']}\" is not "
                             f"a boundary of the mesh (known: "
                             f"{', '.join(sorted(known)) or 'none'})")
    macro = Macro(mesh, m["element"], problem["solver"]["kinematics"], m["integration"])
    mc = problem["micro"]
    if mc["model"] in ("dem", "adaptive") and mc["packing"] is None:
        try:  # every Gauss point holds a copy of its packing
            PARTICLES.check(mc["count"] * macro.n_gp, f"count x Gauss points = "
                            f"{mc['count']} x {macro.n_gp}")
        except LimitError as exc:
            raise SceneError(f"{src}: [micro] {exc}") from None
    return macro


def read_mesh(path, where=None):
    """A scikit-fem mesh (its named boundaries included: gmsh physical groups, the
    sets of a file skfem saved) from a file meshio reads; a :class:`SceneError`
    starting with ``where`` (if given) for anything else.

    meshio prints to stdout and calls ``sys.exit`` on a file it cannot parse: its
    output is captured and turned into the one-line error.
    """
    import contextlib
    import io

    from skfem import Mesh

    lead = "" if where is None else f"{where} "
    if Path(path).is_dir():
        raise SceneError(f"{lead}mesh file {path} is a directory")
    said = io.StringIO()
    try:
        with contextlib.redirect_stdout(said), contextlib.redirect_stderr(said):
            return Mesh.load(path)
    except SystemExit:
        reason = " ".join(said.getvalue().split()).removeprefix("Error: ") or \
            "meshio gave up on it"
    except Exception as err:  # noqa: BLE001 - meshio raises many kinds
        reason = f"{type(err).__name__}: {err}"
    raise SceneError(f"{lead}cannot read mesh file {path}: {reason}")


def _cut_boundaries(problem, mesh):
    """The mesh with the ``[[boundary]]`` parts added to its named boundaries
    (:func:`hmm.conditions.cut_boundary`)."""
    for i, b in enumerate(problem["boundary"]):
        try:
            mesh = cut_boundary(mesh, b["name"], b["of"], b["lo"], b["hi"])
        except ValueError as err:
            raise SceneError(f"{problem['source']}: [[boundary]] #{i + 1} {err}") from None
    return mesh


def build_loads(problem, macro):
    """Supports, the constant and ramped external force vectors (dead loads), and the
    configuration-dependent loads of finite kinematics: the problem's conditions as
    the objects of :mod:`hmm.conditions`, through :func:`hmm.conditions.supports` and
    :func:`hmm.conditions.external_forces`."""
    dirichlet = [Dirichlet(c["boundary"], c["component"], c["value"], c["gradient"],
                           c["origin"], c["point"]) for c in problem["dirichlet"]]
    platens = [Platen(c["boundary"], c["component"]) for c in problem["platen"]]
    periodic = [Periodic(c["boundary"], c["image"]) for c in problem["periodic"]]
    try:
        sup = supports(macro, dirichlet, platens, periodic, problem["load"]["gradient"])
    except ConditionError as err:
        where = f"[[{err.kind}]]" + ("" if err.index is None else f" #{err.index + 1}")
        raise SceneError(f"{problem['source']}: {where} {err.reason}") from None
    free = free_rigid_motions(macro, sup)
    if free:
        raise SceneError(f"{problem['source']}: the supports ([[dirichlet]], [[platen]], "
                         f"[[periodic]]) leave {' and '.join(free)} free: no load step "
                         f"can converge; hold more components (a [[dirichlet]] at a "
                         f"boundary or a point)")
    loads = [Pressure(p["boundary"], p["value"], p["ramp"], p["follower"])
             for p in problem["pressure"]]
    loads += [Traction(t["boundary"], tuple(t["value"]), t["per"])
              for t in problem["traction"]]
    b = problem["body_force"]
    loads.append(BodyForce(tuple(b["value"]), b["per"]))
    return (sup, *external_forces(macro, loads))


def build_porous(problem, macro):
    """The pressure field and the time schedule of a saturated problem
    (:class:`~hmm.porous.PorousMacro`, :class:`~hmm.porous.TimeSchedule`), or
    ``(None, None)`` for a dry one."""
    if problem["fluid"] is None:
        return None, None
    from .porous import Fluid, PorousMacro, TimeSchedule

    fl = problem["fluid"]
    ks = fl["solid_bulk_modulus"]
    fluid = Fluid(permeability=fl["permeability"], viscosity=fl["viscosity"],
                  bulk_modulus=fl["bulk_modulus"], porosity=fl["porosity"],
                  biot=fl["biot"], solid_bulk_modulus=math.inf if ks is None else ks,
                  initial_pressure=fl["initial_pressure"],
                  permeability_law=fl["permeability_law"])
    drained = {c["boundary"]: c["pressure"] for c in problem["drainage"]
               if c["pressure"] is not None}
    inflow = {c["boundary"]: c["flux"] for c in problem["drainage"]
              if c["flux"] is not None}
    tm = problem["time"]
    schedule = TimeSchedule(end=tm["end"], steps=problem["load"]["steps"],
                            first=tm["first"], ramp=tm["ramp"])
    return PorousMacro(macro, fluid, drained, inflow), schedule


def build_farm(problem, macro, progress=None):
    """The micro model of every Gauss point in a farm: a :class:`~hmm.farm.MPIFarm`
    when this process is one of several MPI ranks (every rank must call this), else a
    :class:`~hmm.farm.SerialFarm`.

    DEM points share packings: each distinct packing is generated (or read) once per
    rank and copied into every point that uses it.
    """
    from .farm import make_farm

    return make_farm(macro.n_gp, macro.dim,
                     model_factory(problem, macro.dim, progress, macro.gauss_points()))


def build_models(problem, n, dim, progress=None, points=None):
    """The ``n`` micro models of a validated problem (``points``: the Gauss points'
    coordinates (n, d), needed with ``[[imperfection]]``)."""
    factory = model_factory(problem, dim, progress, points)
    return [factory(g) for g in range(n)]


def spot_of(problem, points):
    """For every Gauss point, the index of the first ``[[imperfection]]`` that holds
    it, or -1.

    Examples
    --------
    >>> p = {"imperfection": [{"center": [0.0, 0.0], "radius": 1.0}]}
    >>> spot_of(p, np.array([[0.5, 0.5], [1.0, 1.0]])).tolist()
    [0, -1]
    """
    points = np.asarray(points, dtype=np.float64)
    spot = np.full(len(points), -1, dtype=np.int64)
    for i, imp in reversed(list(enumerate(problem["imperfection"]))):
        inside = np.linalg.norm(points - np.asarray(imp["center"]), axis=1) <= imp["radius"]
        spot[inside] = i
    return spot


def model_factory(problem, dim, progress=None, points=None):
    """``factory(g)``: a fresh micro model for Gauss point ``g`` in its initial state.

    DEM packings are made once, here, and copied by every call; the packing of an
    ``[[imperfection]]`` is made on first use, so a rank that owns none of its points
    never builds it. ``points`` are the Gauss points' coordinates (n_gp, d).
    """
    from .micro import (Adaptive, DEMMicroModel, Hyperbolic, Hypoelastic, LinearElastic,
                        NeoHookean)

    mc = problem["micro"]
    kind = mc["model"]
    if kind == "linear_elastic":
        return lambda g: LinearElastic(mc["young"], mc["poisson"], dim, mc["stress0"])
    if kind == "hyperbolic":
        return lambda g: Hyperbolic(mc["young"], mc["poisson"], mc["gamma_ref"], dim,
                                    mc["stress0"])
    if kind == "hypoelastic":
        return lambda g: Hypoelastic(mc["young"], mc["poisson"], dim, mc["stress0"])
    if kind == "neo_hookean":
        return lambda g: NeoHookean(mc["young"], mc["poisson"], dim)
    finite = problem["solver"]["kinematics"] == "finite"
    packings = [_packing(problem, k, dim, progress) for k in range(mc["packings"])]
    if problem["imperfection"] and points is None:
        raise ValueError("[[imperfection]] needs the Gauss points' coordinates")
    spot = None if points is None else spot_of(problem, points)
    weak = {}

    def packing_of(g):
        if spot is None or spot[g] < 0:
            return packings[g % len(packings)]
        i = int(spot[g])
        if i not in weak:
            weak[i] = _packing(problem, 0, dim, progress, problem["imperfection"][i])
        return weak[i]

    def factory(g):
        m = DEMMicroModel(clone_rve(packing_of(g)), tangent=mc["tangent"],
                          relax=mc["relax"])
        if kind == "adaptive":
            m = Adaptive(m, mc["strain_threshold"], mc["ratio_threshold"], finite)
        return m

    return factory


def _packing(problem, k, dim, progress, spot=None):
    """Packing ``k`` of ``[micro]``, or the packing of an ``[[imperfection]]``
    (``spot``): the first packing with the spot's friction and consolidation."""
    from dem import LinearSpring
    from dem import rve as rvemod

    mc = dict(problem["micro"])
    src = problem["source"]
    where = "[micro]"
    if spot is not None:
        where = "[[imperfection]]"
        mc.update({key: spot[key] for key in ("consolidation_friction", "mu", "packing")
                   if spot[key] is not None})
    opts = {"damping": mc["damping"], "tol": mc["tol"],
            "max_step_strain": mc["max_step_strain"],
            "max_relax_steps": mc["max_relax_steps"]}
    if mc["packing"] is not None:
        try:
            rve = rvemod.RVE.load_file(mc["packing"], **{k_: v for k_, v in opts.items()
                                                         if k_ != "damping"})
        except (OSError, ValueError) as err:
            raise SceneError(f"{src}: {where} packing: {err}") from None
        if rve.dim != dim:
            raise SceneError(f"{src}: {where} packing is {rve.dim}D, the mesh {dim}D")
        if spot is not None and spot["mu"] is not None:
            rve.set_friction(spot["mu"])
        return rve
    from dem.io.materials import rolling_spec

    from .experiment_config import shape_maker

    law = LinearSpring.from_table(micro_stiffness(mc, dim), rolling=rolling_spec(mc))
    return rvemod.generate(dim, mc["count"], mc["radius"], law, mc["p0"],
                           density=mc["density"], seed=mc["seed"] + k,
                           friction=mc["consolidation_friction"],
                           shape=shape_maker(mc, dim), **opts)


#: [micro] kn [N/m] when the file gives none: per metre of thickness in 2D. Both make
#: kn / (p0 r^(d-2)) = 1e3 at 100 kPa with 1 mm grains, in the range that
#: :func:`dem.rve.generate` asks for
DEFAULT_KN = {2: 1e8, 3: 1e5}


def micro_stiffness(mc, dim):
    """``[micro]`` with its contact stiffnesses: ``kn`` by the dimension
    (:data:`DEFAULT_KN`) and ``kt = kn / 2`` where the file gives none."""
    mc = dict(mc)
    if mc.get("kn") is None:
        mc["kn"] = DEFAULT_KN[dim]
    if mc.get("kt") is None:
        mc["kt"] = 0.5 * mc["kn"]
    return mc


def clone_rve(rve):
    """An independent copy of an RVE in its current state (bit-identical runs)."""
    from dem import rve as rvemod

    snap = rve.snapshot()
    twin = rvemod.RVE(rve.bodies.copy(), rve.law, rve.cell.copy(),
                      damping=rve.sim.damping, dt=rve.sim.dt, threads=rve.sim.threads,
                      **{k: getattr(rve, k) for k in rve._SETTINGS if k != "mass_scale"})
    twin.mass_scale = rve.mass_scale
    twin.restore(snap)
    return twin


def initial_stress_check(problem, farm, tol=0.05):
    """Relative mismatch between constant pressures and the micro models' initial
    stress (a constant pressure should balance it); returned for the log."""
    sig = farm.stress()
    p_micro = -np.trace(sig, axis1=1, axis2=2).mean() / sig.shape[1]
    const = [p["value"] for p in problem["pressure"] if not p["ramp"]]
    if not const or not math.isfinite(p_micro) or p_micro == 0.0:
        return 0.0
    return abs(np.mean(const) - p_micro) / abs(p_micro)
