"""The angle-of-repose benchmark (benchmarks/angle_of_repose.py) at its smallest size:
300 spheres poured onto a rough floor, once without and once with rolling friction.
The pile with mu_roll = 0.4 stands steeper than the one without, both settle, and the
figure drawn from the results (and the committed one, from its JSON) is fit for a
paper by the shared checks of tests/figure_checks.py."""

import json
import math
import runpy
from pathlib import Path

import numpy as np
import pytest
from figure_checks import (assert_all_points_inside, assert_legend_clear,
                           assert_texts_inside, assert_ticks_apart, assert_units, panels,
                           render)

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "angle_of_repose.py"


@pytest.fixture(scope="module")
def bench():
    return runpy.run_path(str(SCRIPT), run_name="angle_of_repose")


@pytest.fixture(scope="module")
def quick(bench):
    return bench["run"]("quick", mu_rolls=(0.0, 0.4), seed=1)


def assert_fit(fig):
    renderer = render(fig)
    assert_texts_inside(fig, renderer)
    for ax in panels(fig):
        assert_units(ax)
        assert_ticks_apart(ax, renderer)
        assert_legend_clear(ax, renderer)
        assert_all_points_inside(ax)
    # the legend below the panels covers none of them
    legend = fig.legends[0].get_window_extent(renderer)
    for ax in panels(fig):
        assert not legend.overlaps(ax.get_window_extent(renderer))


def test_rolling_friction_steepens_the_pile(quick):
    flat, steep = quick["cases"]
    for c in (flat, steep):
        assert c["settled"] and c["ke_ratio"] < 1e-6
        assert c["n"] == 300 and c["n_escaped"] < 0.05 * c["n"]
        assert 0.0 < c["angle_deg"] < 60.0 and c["n_fit_points"] >= 5
    # beyond both fitting uncertainties, not only in the mean
    gap = steep["angle_deg"] - flat["angle_deg"]
    assert gap > steep["angle_err_deg"] + flat["angle_err_deg"], (flat, steep)
    assert steep["pile_height"] > flat["pile_height"]


def test_the_angle_is_the_slope_of_a_cone(bench):
    """Spheres filling a cone whose surface falls at 30 deg measure 30 deg, within the
    fit's uncertainty, and the cone's radius less about a diameter (where the surface
    is a diameter high)."""
    d, radius = 2.0 * bench["R_MEAN"], bench["R_MEAN"]
    rng = np.random.default_rng(0)
    r_cone, slope = 12.0 * d, math.tan(math.radians(30.0))
    n = 20000
    r = r_cone * np.sqrt(rng.uniform(0.0, 1.0, n))  # uniform over the base
    t = rng.uniform(0.0, 2.0 * math.pi, n)
    top = rng.uniform(0.0, 1.0, n) * (r_cone - r) * slope  # under the surface
    # a sphere's top z + r lies ``top`` above the floor spheres' tops (2 R)
    pos = np.column_stack([r * np.cos(t), r * np.sin(t), top + radius])
    res = bench["angle_of_repose"](pos, np.full(n, radius))
    assert abs(res["angle_deg"] - 30.0) < max(0.5, 3.0 * res["angle_err_deg"])
    assert res["angle_err_deg"] < 0.5
    assert r_cone - 2.0 * d <= res["pile_radius"] <= r_cone
    # the highest bin's median: the apex less at most a diameter's fall
    assert r_cone * slope - d <= res["pile_height"] <= r_cone * slope


def test_the_figure_of_the_quick_run_is_fit(bench, quick):
    assert_fit(bench["visualize"](quick))


def test_the_committed_figure_draws_fit_from_its_json(bench):
    data = json.loads((ROOT / "benchmarks" / "results" / "angle_of_repose.json").read_text())
    assert [c["mu_roll"] for c in data["cases"]] == [0.0, 0.05, 0.1, 0.2, 0.4]
    assert_fit(bench["visualize"](data))
