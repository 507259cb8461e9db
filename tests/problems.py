"""Small problem files shared by the tests of ``hmm run`` (run, readers, signals,
environment failures): linear-elastic micro models, so a run takes a second."""


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
