"""Figures fit for a paper, read back through matplotlib's objects: the plate with a
hole (examples/pd_plate_hole.py), the tangent and adaptive benchmark
(benchmarks/hmm_tangent_adaptive.py), the stability map (benchmarks/stability_map.py)
and the colliding polygons (examples/ex03_polygons.py), each drawn from small
synthetic data by the function that draws the committed PNG.

Labelled axes with units, labelled colour bars, titles inside the figure, legends and
insets off the data, every point inside its axes, tick labels and annotations apart.
"""

import json
import runpy
from pathlib import Path

import matplotlib
import numpy as np
import pytest
from figure_checks import (assert_all_points_inside, assert_annotations_apart,
                           assert_colour_bars_labelled, assert_inset_clear,
                           assert_legend_clear, assert_texts_inside, assert_ticks_apart,
                           assert_units, colour_bars, panels, render)

ROOT = Path(__file__).resolve().parents[1]


def script(path):
    """The functions of a script (its main block not run, nothing simulated)."""
    return runpy.run_path(str(ROOT / path), run_name="figures")


def functions(path, *names):
    """Functions ``names`` of a script whose top-level code runs a simulation, compiled
    without that code (their module imports numpy as np, as the examples do)."""
    import ast

    tree = ast.parse((ROOT / path).read_text())
    body = [node for node in tree.body
            if isinstance(node, ast.FunctionDef) and node.name in names]
    assert sorted(node.name for node in body) == sorted(names)
    scope = {"np": np}
    exec(compile(ast.Module(body=body, type_ignores=[]), str(ROOT / path), "exec"), scope)
    return [scope[name] for name in names]


def assert_fit(fig, legends=True):
    """Every panel with units on both axes, tick labels apart and its legend off the
    data; colour bars labelled; titles and labels inside the figure."""
    renderer = render(fig)
    assert_texts_inside(fig, renderer)
    assert_colour_bars_labelled(fig)
    for ax in panels(fig):
        assert_units(ax)
        assert_ticks_apart(ax, renderer)
        if legends:
            assert_legend_clear(ax, renderer)
    return renderer


# ------------------------------------------------------------------ pd_plate_hole
def _plate_frames(n=12):
    """Five frames of an n x n lattice with a hole: intact, one point damaged, a
    crack, and two fragments spread out, with force densities over decades (zeros
    at the start, as at rest)."""
    dx = 1.0 / n
    g = (np.arange(n) + 0.5) * dx
    pos = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
    pos = pos[((pos[:, 0] - 0.5) / 0.1) ** 2 + ((pos[:, 1] - 0.5) / 0.2) ** 2 > 1.0]
    rng = np.random.default_rng(3)
    crack = np.exp(-((pos[:, 0] - 0.5) / dx) ** 2)
    spread = pos + np.c_[np.sign(pos[:, 0] - 0.5) * 0.2, 0.1 * (pos[:, 1] - 0.5)]
    frames = [("t = 0", pos, np.zeros(len(pos)), np.zeros(len(pos))),
              ("first damage", pos, (np.arange(len(pos)) == 7) * 0.25,
               10.0 ** rng.uniform(2, 6, len(pos))),
              ("split", pos, crack, 10.0 ** rng.uniform(3, 7, len(pos))),
              ("halves meet", spread, np.clip(crack + 0.6, 0, 1), rng.uniform(0, 1e8, len(pos))),
              ("after the impact", spread, np.ones(len(pos)), 10.0 ** rng.uniform(5, 9, len(pos)))]
    return frames, dx


def test_the_plate_figure_has_colour_bars_axes_in_metres_and_no_grid():
    plate = script("examples/pd_plate_hole.py")
    frames, dx = _plate_frames()
    with matplotlib.rc_context({"axes.grid": True}):  # a style that turns grids on
        fig = plate["figure"](frames, dx)
    renderer = render(fig)
    axes = np.array(panels(fig)).reshape(2, len(frames))
    assert [ax.get_title() for ax in axes[0]] == [f[0] for f in frames]
    assert [b.get_ylabel() for b in colour_bars(fig)] == ["damage [-]",
                                                         "force density [N/m^3]"]
    assert_texts_inside(fig, renderer)
    for ax in axes.ravel():
        assert not any(line.get_visible() for line in ax.get_xgridlines() + ax.get_ygridlines())
    for ax in axes[:, 0]:
        assert_units(ax, x=False)
        assert ax.get_ylabel() == "y [m]"
    for ax in axes[1]:
        assert_units(ax, y=False)
        assert_ticks_apart(ax, renderer, which="x")
    for ax in axes[:, 0]:
        assert_ticks_apart(ax, renderer, which="y")
    # every panel at one scale, the spread fragments inside it
    assert len({(ax.get_xlim(), ax.get_ylim()) for ax in axes.ravel()}) == 1
    lo, hi = axes[0, 0].get_xlim()
    assert lo < frames[-1][1][:, 0].min() and frames[-1][1][:, 0].max() < hi


def test_the_plate_figure_shows_damage_light_to_dark_and_force_on_a_log_scale():
    from matplotlib.colors import LogNorm

    plate = script("examples/pd_plate_hole.py")
    frames, dx = _plate_frames()
    fig = plate["figure"](frames, dx)
    render(fig)
    axes = np.array(panels(fig)).reshape(2, len(frames))
    for (_, _, damage, _), ax in zip(frames, axes[0], strict=True):
        dots = ax.collections[0]
        np.testing.assert_array_equal(dots.get_array(), damage)  # the fraction, as is
        assert dots.get_clim() == (0.0, 1.0)
    cmap = axes[0, 0].collections[0].get_cmap()
    grey = [np.dot(cmap(v)[:3], [0.299, 0.587, 0.114]) for v in (0.0, 0.5, 1.0)]
    assert grey[0] > 0.75 and grey[0] > grey[1] > grey[2]  # intact light, broken dark
    norms = {id(ax.collections[0].norm) for ax in axes[1]}
    assert len(norms) == 1  # one colour scale for the row
    norm = axes[1, 0].collections[0].norm
    assert isinstance(norm, LogNorm)
    assert norm.vmax == pytest.approx(max(f[3].max() for f in frames))
    # zero force (at rest) is drawn at the bottom of the scale, not left out
    assert np.all(axes[1, 0].collections[0].get_array() == norm.vmin)
    # square markers at least a lattice cell wide on screen: no seams between points
    ax = axes[0, 0]
    side_px = np.sqrt(ax.collections[0].get_sizes()[0]) * fig.dpi / 72.0
    cell_px = ax.get_window_extent().width * dx / np.diff(ax.get_xlim())[0]
    assert cell_px <= side_px < 1.3 * cell_px


# ------------------------------------------------------------------ hmm_tangent_adaptive
def _adaptive(crit, th, saved, largest, end, completed=True):
    return {"criterion": crit, "strain_threshold": th if crit == "strain" else 1e6,
            "ratio_threshold": th if crit == "ratio" else 1e6, "completed": completed,
            "steps_saved": saved, "stopped_at_load_factor": None if completed else 0.4,
            "deviation": {"max_peak": largest, "end_peak": end}}


def _tangent_data():
    """The benchmark's JSON in small: two tangents over four load steps, a sweep with
    points at zero error, thresholds sharing a point, DEM steps saved below -100 %,
    and one run that stopped."""
    u = [0.0, -1e-4, -2e-4, -3e-4, -4e-4]

    def tangent(scale, its):
        return {"curve": {"displacement": u,
                          "reaction": [-4e3 - scale * 2.5e7 * abs(x) ** 0.8 for x in u]},
                "iterations": its, "iterations_per_step": sum(its) / len(its),
                "wall_per_step": 0.5, "deviation": {"max_peak": 0.018}}

    runs = [_adaptive("strain", 1e-4, 0.0, 0.0, 0.0), _adaptive("strain", 1e-3, 0.0, 0.0, 0.0),
            _adaptive("strain", 1.5e-3, 0.04, 0.09, 0.004),
            _adaptive("strain", 3e-3, -0.3, 0.25, 0.007),
            _adaptive("strain", 1.2e-2, 1.0, 1.76, 1.76),
            _adaptive("ratio", 0.3, 0.02, 0.008, 0.008), _adaptive("ratio", 0.5, 0.05, 0.09, 0.009),
            _adaptive("ratio", 0.7, -2.1, 0.65, 0.017), _adaptive("ratio", 1.0, 1.0, 1.76, 1.76),
            _adaptive("ratio", 2.0, 0.5, 0.3, None, completed=False)]
    return {"tangent": {"dem_contact": tangent(1.0, [3, 4, 6, 6]),
                        "dem_perturbation": tangent(1.01, [3, 3, 3, 4])},
            "adaptive": {f"run{k}": r for k, r in enumerate(runs)}}


def test_the_tangent_figure_keeps_every_point_and_label_in_view():
    bench = script("benchmarks/hmm_tangent_adaptive.py")
    fig = bench["visualize"](_tangent_data())
    ax, bx = fig.axes[0], fig.axes[1]
    inset = ax.child_axes[0]
    renderer = assert_fit(fig)
    assert_inset_clear(ax, inset)
    assert_units(inset)
    assert_ticks_apart(inset, renderer)
    assert_all_points_inside(bx)
    assert_annotations_apart(bx, renderer)
    labels = [t.get_text() for t in bx.texts]
    assert "0.0001, 0.001" in labels  # two thresholds on one point: one label
    assert labels.count("1") == 1 and "0.012" in labels
    named = [t.get_text() for t in bx.get_legend().get_texts()]
    assert any(t.startswith("ratio threshold 2: Newton failed") for t in named)
    # the legend is outside the panel, inside the figure
    legend = bx.get_legend().get_window_extent(renderer)
    assert not legend.overlaps(bx.get_window_extent(renderer))
    assert fig.bbox.x0 <= legend.x0 and legend.x1 <= fig.bbox.x1 and fig.bbox.y0 <= legend.y0


@pytest.mark.parametrize("name", ["hmm_tangent_adaptive", "stability_map"])
def test_the_committed_benchmark_results_draw_fit(name):
    """The figures of docs/figures/ as they are drawn from the saved JSON."""
    bench = script(f"benchmarks/{name}.py")
    data = json.loads((ROOT / "benchmarks" / "results" / f"{name}.json").read_text())
    fig = bench["visualize"](data)
    renderer = assert_fit(fig)
    for ax in panels(fig):
        assert_annotations_apart(ax, renderer)
    if name == "hmm_tangent_adaptive":  # both panels, every point in view
        for ax in fig.axes[:2]:
            assert_all_points_inside(ax)


# ------------------------------------------------------------------ stability_map
def _energy_rows(factors, fail_from):
    return [{"factor": f, "energy_error": 1e-2 * f ** 2 if f < fail_from else None,
             "error": None if f < fail_from else "SimulationError"} for f in factors]


def _stability_results():
    """The sweep's JSON in small: every panel's keys, failures included."""
    grid = [0.02, 0.1, 0.3, 0.5, 0.6, 0.8, 1.0, 1.5]
    rve = [{"damping": c, "strain": e, "relax_steps": None if c == 0 else int(50 / c),
            "error": "RelaxationError" if c == 0 else None}
           for c in (0.0, 0.01, 0.1, 0.8) for e in (1e-5, 1e-4, 1e-3, 1e-2)]
    newton = [{"control": control, "level": level, "n_steps": n,
               "iterations": 4 * n + (30 if level and level > 1 else 0),
               "error": "SolverError" if level and level > 1 else None}
              for control, level in (("displacement", None), ("pressure", 0.9),
                                     ("pressure", 1.05)) for n in (1, 4, 16, 64)]
    corner = [{"side": 1.0, "tol_1e-08": {"error": err, "depth": d, "iterations": 54},
               "tol_1e-06": {"depth": d}}
              for d, err in ((1e-4, "stalled"), (1e-3, "stalled"), (3e-2, None), (1e-1, None))]
    return {
        "spheres": {kind: {"rows": _energy_rows(grid, lim), "dim": dim, "n": n,
                           "verlet_limit": lim, "refused_from": 0.45}
                    for kind, dim, n, lim in (("hex", 2, 36, 0.58), ("fcc", 3, 32, 0.5))},
        "polyhedra": {"rows": _energy_rows(grid + [3.0, 5.0], 9.0), "refused_from": 0.45},
        "peridynamics": {"rows": _energy_rows(grid, 1.0)},
        "rve": {"rows": rve, "max_relax_steps": 20000},
        "newton": {"rows": newton},
        "admm": {"parallel": [{"tilt": t, "iterations": 5} for t in (0.0, 1e-6, 1e-2, 0.3)],
                 "deep": [{"depth": d, "iterations": 5} for d in (1e-5, 1e-2, 0.5)],
                 "thin": [{"thickness": h, "iterations": 2} for h in (1e-3, 1e-1)],
                 "corner": corner, "fallback": {"cold_iterations": 5}}}


def test_the_stability_map_keeps_legends_and_titles_off_the_data():
    bench = script("benchmarks/stability_map.py")
    fig = bench["visualize"](_stability_results())
    assert len(panels(fig)) == 6
    assert_fit(fig)
    for ax in panels(fig):
        assert len(ax.get_title()) < 50
        assert ax.get_legend() is not None


def test_the_stability_map_redraws_from_its_json_without_running(tmp_path, capsys):
    bench = script("benchmarks/stability_map.py")
    glob = bench["main"].__globals__
    glob["OUT"], glob["PNG"] = tmp_path / "map.json", tmp_path / "map.png"
    with pytest.raises(SystemExit) as stop:
        bench["main"](["--figure"])
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and "map.json" in err and "\n" not in err
    res = _stability_results()
    del res["admm"]
    glob["OUT"].write_text(json.dumps(res))
    with pytest.raises(SystemExit):
        bench["main"](["--figure"])
    assert "admm" in capsys.readouterr().err
    glob["OUT"].write_text(json.dumps(_stability_results()))
    bench["main"](["--figure"])
    assert glob["PNG"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# ------------------------------------------------------------------ ex03_polygons
def test_the_polygon_figure_has_titles_inside_and_its_legend_above_the_curves():
    import dem
    from dem.shapes import ConvexPolygon

    square = ConvexPolygon(np.array([[0.1, 0.0], [0.0, 0.1], [-0.1, 0.0], [0.0, -0.1]]))
    start = dem.Bodies.empty(2)
    start.add_shapes(square, [[0.0, 0.0], [0.3, 0.0]], 1000.0, rot=[0.0, 0.5])
    end = start.copy()
    end.pos[:2] += [[0.05, 0.1], [0.2, 0.1]]
    t = np.linspace(0.0, 1.5, 151)
    elastic = 0.6 * np.exp(-(((t - 0.85) / 0.01) ** 2))
    kinetic = 1.7 - 0.3 * (t > 0.85) - elastic
    figure, _ = functions("examples/ex03_polygons.py", "figure", "_draw")
    fig = figure(start, end, {"t": t, "kinetic": kinetic, "elastic": elastic})
    renderer = assert_fit(fig)
    ax, ax2 = panels(fig)
    assert ax.get_title() and ax2.get_title()
    assert_all_points_inside(ax2)
    assert len(ax2.get_legend().get_texts()) == 3
    assert len(ax.patches) == 4  # two polygons, at the start and at the end
    assert_annotations_apart(ax2, renderer)
