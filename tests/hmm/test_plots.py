"""The figures of a multiscale run (hmm.plots), read back through matplotlib's objects:
labelled axes with units, labelled colour bars, the driven force in the driven
direction, tick labels that do not run together."""

import numpy as np
import pytest
from figure_checks import (assert_colour_bars_labelled, assert_texts_inside,
                           assert_ticks_apart, colour_bars, panels, render)

from hmm.plots import (fields_figure, length_unit, load_displacement_figure, scaled_unit,
                       slice_polygons, slices_figure)


def _curve(steps=9, push=-8e-4, force=1.4e4):
    """A top pushed down by ``push`` carrying up to ``force`` in y; a bottom held."""
    t = np.linspace(0.0, 1.0, steps)
    u_top = np.zeros((steps, 2))
    u_top[:, 1] = push * t
    f_top = np.zeros((steps, 2))
    f_top[:, 1] = -force * np.sqrt(t)
    f_top[:, 0] = 123.0  # a component the plot must not show
    return {"displacement/top": u_top, "force/top": f_top,
            "displacement/bottom": np.zeros((steps, 2)),
            "force/bottom": -f_top}


def _no_overlap(fig, ax):
    renderer = render(fig)
    assert_ticks_apart(ax, renderer, minimum=3)
    assert_texts_inside(fig, renderer)


def test_the_load_displacement_figure_shows_the_driven_force_in_mm_and_kn():
    c = _curve()
    fig = load_displacement_figure(c, [("top", 1), ("bottom", 1)], 2)
    ax = fig.axes[0]
    assert len(ax.lines) == 1  # the bottom did not move: no vertical line for it
    x, y = ax.lines[0].get_data()
    np.testing.assert_allclose(x, 1e3 * 8e-4 * np.linspace(0.0, 1.0, 9))  # [mm]
    np.testing.assert_allclose(y, 1e-3 * -c["force/top"][:, 1])  # [kN/m], push positive
    assert ax.get_xlabel() == "displacement of top in -y [mm]"
    assert ax.get_ylabel() == "reaction on top in -y [kN/m]"
    assert ax.get_legend() is None  # one curve: the labels say what it is
    _no_overlap(fig, ax)


def test_several_driven_boundaries_get_a_legend_and_3d_forces_are_in_newtons():
    c = _curve(force=350.0)
    c["displacement/right"] = -0.5 * c["displacement/top"][:, ::-1]
    c["force/right"] = 0.5 * c["force/top"][:, ::-1]
    fig = load_displacement_figure(c, [("top", 1), ("right", 0)], 3)
    ax = fig.axes[0]
    assert [line.get_label() for line in ax.lines] == ["top (-y)", "right (+x)"]
    assert ax.get_legend() is not None
    assert ax.get_xlabel().startswith("prescribed displacement [mm]")
    assert ax.get_ylabel() == "reaction in the driven direction [N]"
    _no_overlap(fig, ax)


def test_the_field_figure_labels_axes_and_colour_bars():
    x, y = np.meshgrid(np.linspace(0.0, 0.04, 3), np.linspace(0.0, 0.08, 3))
    pts = np.c_[x.ravel(), y.ravel()]
    cells = np.array([[0, 1, 4, 3], [1, 2, 5, 4], [3, 4, 7, 6], [4, 5, 8, 7]])
    fig = fields_figure(pts, cells,
                        [(np.full(4, 0.0113), "deviatoric strain [-]", "viridis",
                          (None, None)),
                         (np.array([0.19, 0.2, 0.21, 0.25]), "void ratio [-]", "magma",
                          (None, None))],
                        "last step")
    renderer = render(fig)
    bars = colour_bars(fig)
    assert len(panels(fig)) == 2 and len(bars) == 2
    assert_colour_bars_labelled(fig)
    assert_texts_inside(fig, renderer)
    for ax in panels(fig):
        assert (ax.get_xlabel(), ax.get_ylabel()) == ("x [mm]", "y [mm]")
        assert ax.get_xlim()[1] == pytest.approx(40.0, rel=0.1)
    assert [b.get_ylabel() for b in bars] == ["deviatoric strain [-]", "void ratio [-]"]
    # a uniform field: limits around its value, no offset text such as "1e-16+1.13e-2"
    assert bars[0].yaxis.get_offset_text().get_text() == ""
    lo, hi = panels(fig)[0].collections[0].get_clim()
    assert lo < 0.0113 < hi
    assert fig._suptitle.get_text() == "last step"


def test_units_follow_the_magnitude():
    assert scaled_unit([2.5e6], "N")[1] == "MN" and scaled_unit([0.5], "N")[1] == "N"
    assert length_unit([3e-7]) == (1e6, "µm") and length_unit([2.0]) == (1.0, "m")


def _area(q):
    x, y = q[:, 0], q[:, 1]
    return 0.5 * abs(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1)))


def _distorted_box(element, cells, seed=3):
    """A 5 x 10 x 5 cm box of hexahedra (corners in VTK order) or tetrahedra, its
    interior vertices moved by up to a fifth of a cell."""
    import hmm
    from hmm.run_figures import HEX_ORDER

    size = np.array([0.05, 0.1, 0.05])
    mesh = hmm.structured_mesh(element, list(size), cells)
    p = mesh.p.copy()
    inner = np.all((p > 1e-12) & (p < size[:, None] - 1e-12), axis=0)
    p[:, inner] += np.random.default_rng(seed).uniform(-0.2, 0.2, (3, inner.sum())) * \
        (size / cells)[:, None]
    return p.T, (mesh.t[HEX_ORDER].T if element == "hex1" else mesh.t.T), size


@pytest.mark.parametrize("element", ["hex1", "tet1"])
def test_slices_of_a_distorted_mesh_tile_the_cross_section(element):
    """Whatever the cells' shapes, the cut polygons of a plane through a box tile its
    cross-section exactly (their areas sum to it), every cut cell straddles the plane,
    and a plane through a layer of vertices draws each face once."""
    pts, cells, size = _distorted_box(element, [2, 4, 2])
    for axis, at in ((0, 0.0137), (1, 0.0421), (2, 0.031), (1, 0.05)):
        polys, cut = slice_polygons(pts, cells, axis, at)
        area = np.prod(np.delete(size, axis))
        assert sum(_area(q) for q in polys) == pytest.approx(area, rel=1e-12)
        side = pts[cells[cut], axis] - at
        assert np.all((side.min(axis=1) < 0.0) & (side.max(axis=1) >= 0.0))


def test_the_slices_figure_shows_three_planes_on_one_colour_scale():
    pts, cells, _ = _distorted_box("hex1", [2, 4, 2])
    values = np.linspace(0.0, 0.02, len(cells))
    fig = slices_figure(pts, cells, values, "deviatoric strain [-]", "last step")
    renderer = render(fig)
    axs = panels(fig)
    assert len(axs) == 3 and len(colour_bars(fig)) == 1
    assert_colour_bars_labelled(fig)
    assert_texts_inside(fig, renderer)
    assert [(ax.get_xlabel(), ax.get_ylabel()) for ax in axs] == [
        ("z [mm]", "y [mm]"), ("x [mm]", "y [mm]"), ("x [mm]", "z [mm]")]
    assert [ax.get_title().split(" = ")[0] for ax in axs] == ["x", "z", "y"]
    assert {ax.collections[0].get_clim() for ax in axs} == {(0.0, 0.02)}
    for ax in axs:  # the planes run through the middle of the box
        assert abs(float(ax.get_title().split(" = ")[1].split()[0]) -
                   {"x": 25.0, "z": 25.0, "y": 50.0}[ax.get_title()[0]]) < 12.5
