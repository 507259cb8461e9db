"""The schema of a problem file (:mod:`hmm.problem`): every section and key, with units
and ranges, and the reference generated from it (:func:`schema_markdown`).
"""

from dem.io.schema import REQUIRED, Key, Range, Section
from dem.io.schema import schema_markdown as _markdown
from dem.limits import Limit
from dem.shapes.registry import packing_shapes

__all__ = ["ANALYTIC", "COMPONENTS", "ELEMENTS_2D", "ELEMENTS_3D", "KINEMATICS",
           "LOAD_STEPS", "MESH_ELEMENTS", "MICRO_MODELS", "QUADRATURE_CHOICE", "SCHEMA",
           "SMALL_ONLY", "schema_markdown"]

POSITIVE = Range(0.0, lo_closed=False)
NONNEGATIVE = Range(0.0)
COMPONENTS = ("x", "y", "z")
#: element names of 2D and 3D meshes (hmm.macro.ELEMENTS gives their classes)
ELEMENTS_2D = ("quad1", "quad2", "quad8", "tri1", "tri2")
ELEMENTS_3D = ("hex1", "hex20", "hex27", "tet1", "tet10")
#: elements whose Gauss rule [mesh] integration chooses (hmm.macro.INTEGRATION)
QUADRATURE_CHOICE = ("quad2", "quad8", "hex20", "hex27")
#: most elements of a mesh ([mesh] size and cells, or a file); each has Gauss points
MESH_ELEMENTS = Limit(10**6, "HMM_MAX_ELEMENTS", "elements")
#: most load steps of a run (the schedule is an array of that length)
LOAD_STEPS = Limit(10**6, "HMM_MAX_LOAD_STEPS", "load steps")
#: micro models of [micro] model; the analytic ones take young and poisson
MICRO_MODELS = ("dem", "adaptive", "linear_elastic", "hyperbolic", "hypoelastic",
                "neo_hookean")
ANALYTIC = ("linear_elastic", "hyperbolic", "hypoelastic", "neo_hookean")
#: the small-strain laws (not objective): small kinematics only
SMALL_ONLY = ("linear_elastic", "hyperbolic")
KINEMATICS = ("small", "finite")
#: a load step's first guesses (hmm.coupling.SolverSettings.predictor)
PREDICTORS = ("tangent", "extrapolated")

SCHEMA = {
    "mesh": Section(doc="The macro domain and its finite elements.", required=True, keys={
        "dim": Key("int", default=2, choices=(2, 3), doc="2 (plane strain) or 3."),
        "element": Key("str", default="quad1",
                       choices=ELEMENTS_2D + ELEMENTS_3D,
                       doc="Element type (2D: quad1 quad2 quad8 tri1 tri2; 3D: hex1 "
                           "hex20 hex27 tet1 tet10)."),
        "integration": Key("str", choices=("reduced", "full"),
                           doc="Quadratic quadrilaterals and hexahedra (quad2 quad8 "
                               "hex20 hex27): 2 (reduced) or 3 (full) Gauss points per "
                               "axis; default reduced for quad8 and hex20, full for "
                               "quad2 and hex27."),
        "size": Key("vector", "m", range=POSITIVE,
                    doc="Edge lengths of the rectangle/box [0, size]."),
        "cells": Key("vector", range=Range(1.0), doc="Elements along each axis."),
        "file": Key("path", doc="A mesh file scikit-fem reads (instead of size/cells)."),
        **{a: Key("coordinates", "m",
                  doc=f"The element edges along {a} (instead of size and cells, "
                      f"given for every axis): a graded mesh.") for a in "xyz"},
    }),
    "boundary": Section(doc="Named parts of the mesh's boundaries (a footing on the top "
                            "face, say): the facets of `of` whose midpoints lie in the "
                            "box [lo, hi].", array=True, keys={
        "name": Key("str", default=REQUIRED, doc="Name of the new boundary."),
        "of": Key("str", default=REQUIRED, doc="The boundary it is cut from."),
        "lo": Key("vector", "m", default=REQUIRED, doc="Lower corner of the box."),
        "hi": Key("vector", "m", default=REQUIRED, doc="Upper corner of the box."),
    }),
    "dirichlet": Section(doc="Prescribed displacements, ramped with the load factor: a "
                             "uniform `value` in one component, or an affine "
                             "displacement u = G (x - origin) (`gradient`), in every "
                             "component or in `component` only (x the initial "
                             "position of each node).", array=True, keys={
        "boundary": Key("str", doc="Named boundary of the mesh (this or `point`)."),
        "point": Key("vector", "m", doc="A vertex of the mesh (this or `boundary`): a "
                                         "point support, e.g. the middle of a smooth "
                                         "base held against rigid sliding."),
        "component": Key("str", choices=COMPONENTS,
                         doc="Displacement component (required with `value`; with "
                             "`gradient`, default every component)."),
        "value": Key("float", "m", default=0.0, doc="Value at the end of the schedule."),
        "gradient": Key("tensor", doc="The displacement gradient G of an affine "
                                      "displacement u = G (x - origin) at the end of "
                                      "the schedule, instead of `value`: d rows of d "
                                      "numbers (a number g: g I)."),
        "origin": Key("vector", "m", doc="The point an affine displacement leaves in "
                                         "place (default 0)."),
    }),
    "periodic": Section(doc="Periodic boundaries: `boundary` and its `image` (the same "
                            "nodes shifted by L) are tied node by node, u(x + L) = "
                            "u(x) + G L, with G the average displacement gradient "
                            "[load] gradient; a corner on two pairs is tied to all its "
                            "images. Hold one node against rigid translation with a "
                            "point [[dirichlet]] in every component.", array=True,
                        keys={
        "boundary": Key("str", default=REQUIRED, doc="Named boundary of the mesh."),
        "image": Key("str", default=REQUIRED,
                     doc="The opposite boundary, `boundary` shifted by L."),
    }),
    "platen": Section(doc="A rigid, frictionless platen: one displacement component "
                          "of a boundary is a single unknown, pushed by the loads on "
                          "the boundary (a pressure or a traction): the plates of "
                          "Mandel's problem, a rigid footing under a force.",
                      array=True, keys={
        "boundary": Key("str", default=REQUIRED, doc="Named boundary of the mesh."),
        "component": Key("str", default=REQUIRED, choices=COMPONENTS,
                         doc="The component that moves as one."),
    }),
    "pressure": Section(doc="Normal pressure on a boundary (compression positive).",
                        array=True, keys={
        "boundary": Key("str", default=REQUIRED, doc="Named boundary of the mesh."),
        "value": Key("float", "Pa", default=REQUIRED, doc="Pressure."),
        "ramp": Key("bool", default=False,
                    doc="Grow with the load factor (else present from the start)."),
        "follower": Key("bool", default=True,
                        doc="Under finite kinematics, act normal to the deformed "
                            "boundary, on its current area (false: a dead load on "
                            "the initial boundary)."),
    }),
    "traction": Section(doc="Traction vector on a boundary, ramped.", array=True, keys={
        "boundary": Key("str", default=REQUIRED, doc="Named boundary of the mesh."),
        "value": Key("vector", "Pa", default=REQUIRED, doc="Traction at load factor 1."),
        "per": Key("str", default="reference", choices=("reference", "current"),
                   doc="Under finite kinematics, per unit initial (reference) or "
                       "current area."),
    }),
    "body_force": Section(doc="Body force density, ramped.", keys={
        "value": Key("vector", "N/m^3", default=0.0, doc="Force per unit volume."),
        "per": Key("str", default="reference", choices=("reference", "current"),
                   doc="Under finite kinematics, per unit initial (reference) volume "
                       "(gravity: rho_0 g) or current volume."),
    }),
    "load": Section(doc="The load schedule.", keys={
        "steps": Key("int", default=10, range=Range(1.0), doc="Number of load steps."),
        "gradient": Key("tensor", doc="The average displacement gradient G of the "
                                      "[[periodic]] pairs at the end of the schedule, "
                                      "d rows of d numbers (a number g: g I; default "
                                      "0)."),
    }),
    "micro": Section(doc="The micro model at every Gauss point.", required=True,
                     variant="model", keys={
        "model": Key("str", default=REQUIRED, choices=MICRO_MODELS,
                     doc="dem: an RVE per point; adaptive: DEM only where needed; "
                         "linear_elastic / hyperbolic: small-strain analytic laws; "
                         "hypoelastic (Jaumann rate) / neo_hookean: objective "
                         "analytic laws."),
        "young": Key("float", "Pa", default=REQUIRED, range=POSITIVE,
                     only=ANALYTIC, doc="Young's modulus (small strain)."),
        "poisson": Key("float", default=REQUIRED, range=Range(-1.0, 0.5, False, False),
                       only=ANALYTIC, doc="Poisson's ratio (small strain)."),
        "gamma_ref": Key("float", default=REQUIRED, range=POSITIVE, only=("hyperbolic",),
                         doc="Reference shear strain of the hyperbolic law."),
        "stress0": Key("float", "Pa", default=0.0,
                       only=("linear_elastic", "hyperbolic", "hypoelastic"),
                       doc="Initial isotropic stress (tension positive)."),
        "packing": Key("path", only=("dem", "adaptive"),
                       doc="A packing saved by `hmm rve` or RVE.save (else generated)."),
        "packings": Key("int", default=1, range=Range(1.0), only=("dem", "adaptive"),
                        doc="Distinct generated packings (seeds seed..seed+n-1), "
                            "assigned to Gauss points in turn: material variability."),
        "count": Key("int", default=100, range=Range(4.0), only=("dem", "adaptive"),
                     doc="Particles per generated packing."),
        "radius": Key("radius", "m", default=[0.8e-3, 1.2e-3], range=POSITIVE,
                      only=("dem", "adaptive"), doc="Radius or [min, max]."),
        "density": Key("float", "kg/m^3", default=2650.0, range=POSITIVE,
                       only=("dem", "adaptive"), doc="Particle density."),
        "p0": Key("float", "Pa", default=1e5, range=POSITIVE, only=("dem", "adaptive"),
                  doc="Consolidation pressure of generated packings."),
        "seed": Key("int", default=0, range=NONNEGATIVE, only=("dem", "adaptive"),
                    doc="Seed of the first generated packing."),
        "consolidation_friction": Key("float", default=0.0, range=NONNEGATIVE,
                                      only=("dem", "adaptive"),
                                      doc="Friction while consolidating (lower: denser)."),
        "shape": Key("str", default="sphere", choices=tuple(packing_shapes()),
                     only=("dem", "adaptive"),
                     doc="Particle shape of generated packings, as [packing] shape of "
                         "`hmm rve` (polygon: 2D only)."),
        "sides": Key("int", range=Range(3.0, 64.0), only=("dem", "adaptive"),
                     doc="Corners of each polygon, or the fewest with sides_max "
                         "(default 6)."),
        "sides_max": Key("int", range=Range(3.0, 64.0), only=("dem", "adaptive"),
                         doc="Optional: the most corners of a polygon."),
        "kn": Key("float", "N/m", range=POSITIVE, only=("dem", "adaptive"),
                  doc="Normal contact stiffness (linear law); default 1e8 in 2D (per "
                      "metre of thickness), 1e5 in 3D: kn / (p0 r^(d-2)) = 1e3 at "
                      "100 kPa and 1 mm grains in both."),
        "kt": Key("float", "N/m", range=NONNEGATIVE, only=("dem", "adaptive"),
                  doc="Tangential contact stiffness; default kn / 2."),
        "mu": Key("float", default=0.5, range=NONNEGATIVE, only=("dem", "adaptive"),
                  doc="Friction coefficient."),
        "mu_roll": Key("float", default=0.0, range=NONNEGATIVE, only=("dem", "adaptive"),
                       doc="Rolling-friction coefficient of the contacts (dem.Rolling; "
                           "0: none)."),
        "eta_roll": Key("float", default=0.0, range=NONNEGATIVE, only=("dem", "adaptive"),
                        doc="Damping ratio of the rolling dashpot."),
        "damping": Key("float", default=0.5, range=Range(0.0, 1.0, True, False),
                       only=("dem", "adaptive"), doc="Local damping of the RVEs."),
        "tol": Key("float", default=1e-3, range=POSITIVE, only=("dem", "adaptive"),
                   doc="Unbalanced-force ratio that ends a relaxation."),
        "max_step_strain": Key("float", default=1e-5, range=POSITIVE,
                               only=("dem", "adaptive"), doc="Largest strain per step."),
        "max_relax_steps": Key("int", default=200000, range=Range(1.0),
                               only=("dem", "adaptive"), doc="Step cap of a relaxation."),
        "relax": Key("bool", default=True, only=("dem", "adaptive"),
                     doc="Relax each RVE call to tol; false: stop once the strain "
                         "increment is imposed (YADE FEMxDEM's call)."),
        "tangent": Key("str", default="contact", choices=("contact", "perturbation"),
                       only=("dem", "adaptive"), doc="Tangent operator of the RVEs "
                       "(perturbation: relaxed probes, so relax = true only)."),
        "strain_threshold": Key("float", default=1e-4, range=POSITIVE, only=("adaptive",),
                                doc="Strain after which a point runs its RVE."),
        "ratio_threshold": Key("float", default=0.3, range=POSITIVE, only=("adaptive",),
                               doc="Stress ratio q/p after which a point runs its RVE."),
    }),
    "imperfection": Section(doc="Weak spots: the Gauss points inside a disc (a ball in "
                                "3D) start from their own packing, so that localisation "
                                "has a place to begin.", array=True, keys={
        "center": Key("vector", "m", default=REQUIRED, doc="Centre of the spot."),
        "radius": Key("float", "m", default=REQUIRED, range=POSITIVE,
                      doc="Radius of the spot."),
        "consolidation_friction": Key("float", range=NONNEGATIVE,
                                      doc="Friction while consolidating the spot's "
                                          "packing (higher: looser); default as [micro]."),
        "mu": Key("float", range=NONNEGATIVE,
                  doc="Contact friction in the spot; default as [micro]."),
        "packing": Key("path", doc="A packing file for the spot (else generated)."),
    }),
    "solver": Section(doc="Kinematics, Newton iterations and step cutting.", keys={
        "kinematics": Key("str", choices=KINEMATICS,
                          doc="small: a fixed mesh and the symmetric strain "
                              "increment; finite: updated Lagrangian, the mesh moves "
                              "and the RVEs get the whole displacement gradient "
                              "(default: finite for dem, adaptive, hypoelastic and "
                              "neo_hookean; small for linear_elastic and "
                              "hyperbolic, which are small-strain laws)."),
        "tol_residual": Key("float", default=1e-3, range=POSITIVE,
                            doc="Free residual over internal force norm."),
        "tol_displacement": Key("float", default=1e-3, range=POSITIVE,
                                doc="Correction over step displacement norm."),
        "max_iterations": Key("int", default=10, range=Range(1.0),
                              doc="Newton iterations before a step is cut."),
        "min_step": Key("float", default=1.0 / 64.0, range=Range(0.0, 1.0, False, True),
                        doc="Smallest step, as a fraction of the nominal one."),
        "aitken": Key("bool", default=True,
                      doc="Aitken relaxation of successive Newton corrections (steadies "
                          "the DEM's approximate tangent; false: plain Newton, "
                          "quadratic with an exact tangent)."),
        "predictor": Key("str", default="tangent", choices=PREDICTORS,
                         doc="A load step's first guess: tangent (a solve with the "
                             "committed tangents) or extrapolated (the last step's "
                             "displacements, scaled: fewer iterations under a steady "
                             "load; dry problems only)."),
        "coupling": Key("str", choices=("monolithic", "fixed_stress"),
                        doc="A saturated problem: Newton on displacement and pore "
                            "pressure at once (monolithic, the default), or the "
                            "fixed-stress split (the flow, then the mechanics, in each "
                            "iteration; YADE FEMxDEM's msFEMup)."),
        "check_residual": Key("bool", default=True,
                              doc="Converge on residual and correction; false: on the "
                                  "correction over the step's displacement (YADE "
                                  "FEMxDEM's criterion; a cut step's scaled to the "
                                  "nominal step) or the residual, either."),
    }),
    "fluid": Section(doc="The pore fluid of a saturated problem (Biot's u-p "
                         "equations, hmm.porous): with it the micro models give the "
                         "effective stress, [time] sets the steps in seconds and "
                         "[[drainage]] the hydraulic boundaries. Needs a quadratic "
                         "element (quad8 quad2 tri2 hex20 hex27 tet10); [solver] "
                         "kinematics is \"small\" unless set.", keys={
        "permeability": Key("tensor", "m^2", range=POSITIVE,
                            doc="Intrinsic permeability k (required): a number "
                                "(isotropic) or a d x d symmetric positive definite "
                                "tensor."),
        "viscosity": Key("float", "Pa s", default=1e-3, range=POSITIVE,
                         doc="Dynamic viscosity of the fluid (water: 1e-3)."),
        "bulk_modulus": Key("float", "Pa", default=2.2e9, range=POSITIVE,
                            doc="Bulk modulus of the fluid (water: 2.2e9)."),
        "porosity": Key("float", default=0.4, range=Range(0.0, 1.0, False, False),
                        doc="Porosity n, which weighs the fluid's compressibility in "
                            "the storage 1/M = n/K_f + (biot - n)/K_s."),
        "biot": Key("float", default=1.0, range=Range(0.0, 1.0, False, True),
                    doc="Biot's coefficient alpha, in [porosity, 1]."),
        "solid_bulk_modulus": Key("float", "Pa", range=POSITIVE,
                                  doc="Bulk modulus of the grains K_s (default: "
                                      "incompressible grains)."),
        "initial_pressure": Key("float", "Pa", default=0.0,
                                doc="Uniform pore pressure at the start."),
        "permeability_law": Key("str", default="constant",
                                choices=("constant", "kozeny_carman"),
                                doc="kozeny_carman: the permeability scales with n^3 / "
                                    "(1 - n)^2 from its value at porosity, n following "
                                    "the volumetric strain at each Gauss point."),
    }),
    "drainage": Section(doc="Hydraulic conditions of a saturated problem: every "
                            "boundary not named here is impermeable.", array=True,
                        keys={
        "boundary": Key("str", default=REQUIRED, doc="Named boundary of the mesh."),
        "pressure": Key("float", "Pa", doc="Drained: the pore pressure held on the "
                                           "boundary from the first step on (this or "
                                           "flux)."),
        "flux": Key("float", "m/s", doc="Fluid volume entering per unit area and time "
                                        "(negative: leaving); this or pressure."),
    }),
    "time": Section(doc="The time of a saturated problem: [load] steps steps reach "
                        "end.", keys={
        "end": Key("float", "s", range=POSITIVE, doc="End of the run (required)."),
        "first": Key("float", "s", range=POSITIVE,
                     doc="The first step; the later ones grow geometrically to reach "
                         "end (default: equal steps)."),
        "ramp": Key("float", "s", default=0.0, range=NONNEGATIVE,
                    doc="The load factor rises from 0 to 1 over this time (0: the whole "
                        "load in the first step, carried undrained at first)."),
    }),
    "output": Section(doc="Where results go.", keys={
        "dir": Key("str", doc="Output directory; default output/<file stem>."),
        "every": Key("int", default=1, range=Range(1.0),
                     doc="Load steps between field frames."),
        "checkpoint_every": Key("int", default=0, range=NONNEGATIVE,
                                doc="Load steps between checkpoints (0: none)."),
    }),
}


def schema_markdown():
    """The problem file reference (Markdown), generated from :data:`SCHEMA`."""
    return _markdown(SCHEMA)
