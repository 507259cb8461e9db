"""Small input files shared by the tests: problem files of ``hmm run`` (run, readers,
signals, environment failures) with linear-elastic micro models, so a run takes a
second; sweeps of ``hmm batch`` (batch, MPI batch, signals) of small disk packings;
the 3D triaxial example at the tests' size (serial and MPI)."""

from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def small_triaxial():
    """examples/triaxial_3d.toml at the size of the tests: 1 x 2 x 1 hex20 (16 Gauss
    points), 60-sphere RVEs, the top pushed 0.2 mm (0.2 %) in two steps."""
    from hmm.problem import load_problem

    prob = load_problem(EXAMPLES / "triaxial_3d.toml")
    prob["mesh"]["cells"] = [1, 2, 1]
    prob["micro"]["count"] = 60
    prob["load"]["steps"] = 2
    next(d for d in prob["dirichlet"]
         if d["boundary"] == "top" and d["component"] == "y")["value"] = -0.0002
    prob["output"]["every"] = 1
    return prob


def elastic_problem(steps, cells=(2, 2), checkpoint_every=None):
    """A 1 m x 2 m sample of linear-elastic points compressed by 1 cm at its top,
    held at its bottom (y) and left side (x), in ``steps`` load steps."""
    text = f"""
[mesh]
size = [1.0, 2.0]
cells = [{cells[0]}, {cells[1]}]

[[dirichlet]]
boundary = "bottom"
component = "y"

[[dirichlet]]
boundary = "left"
component = "x"

[[dirichlet]]
boundary = "top"
component = "y"
value = -0.01

[micro]
model = "linear_elastic"
young = 1e6
poisson = 0.3

[load]
steps = {steps}
"""
    if checkpoint_every is not None:
        text += f"\n[output]\ncheckpoint_every = {checkpoint_every}\n"
    return text


def sweep_text(count, seed, axial_strain, increment, confining="[5e4, 1e5, 2e5]"):
    """A sweep of drained biaxial tests on ``count``-disk packings, one experiment per
    confining pressure [Pa] of ``confining`` (the TOML array, as written)."""
    return f"""
[base.packing]
count = {count}
radius = [0.8e-3, 1.2e-3]
p0 = 1e5
seed = {seed}
[base.contact]
law = "linear"
kn = 1e8
kt = 5e7
mu = 0.5
[base.test]
axial_strain = {axial_strain}
increment = {increment}
[sweep.grid]
"test.confining" = {confining}
"""
