"""Checks of a figure fit for a paper, made through matplotlib's objects after the
figure is laid out as a PNG would be: axis labels with units, labelled colour bars,
titles and labels inside the figure, tick labels, annotations and legends that do not
run into each other or into the data.

Shared by tests/test_figures.py and tests/hmm/test_plots.py (``tests/`` is on
``sys.path``).
"""

import itertools
import re

import numpy as np

#: a unit in brackets, "[-]" for a dimensionless quantity
UNIT = re.compile(r"\[[^\]]+\]")


def render(fig):
    """Lay ``fig`` out as a PNG would be (an Agg canvas, drawn); its renderer."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return canvas.get_renderer()


def colour_bars(fig):
    """The colour-bar axes of ``fig``."""
    return [ax for ax in fig.axes if ax.get_label() == "<colorbar>"]


def panels(fig):
    """The axes of ``fig`` that are not colour bars."""
    return [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]


def assert_units(ax, x=True, y=True):
    """``ax``'s x and y labels are there and carry a unit in brackets."""
    checks = [("x", ax.get_xlabel())] * x + [("y", ax.get_ylabel())] * y
    for axis, label in checks:
        assert UNIT.search(label), f"{axis} label {label!r} of {ax.get_title()!r} has no unit"


def assert_colour_bars_labelled(fig):
    """Every colour bar of ``fig`` has a label (with a unit)."""
    for bar in colour_bars(fig):
        label = bar.get_ylabel() or bar.get_xlabel()
        assert UNIT.search(label), f"colour bar label {label!r} has no unit"


def _texts(fig):
    """Titles, suptitle and axis labels of ``fig`` that show text."""
    out = [t for t in (fig._suptitle, fig._supxlabel, fig._supylabel) if t is not None]
    for ax in fig.axes:
        out += [ax.title, ax._left_title, ax._right_title,
                ax.xaxis.label, ax.yaxis.label]
    return [t for t in out if t.get_visible() and t.get_text()]


def assert_texts_inside(fig, renderer):
    """No title, suptitle or axis label extends outside the figure."""
    box = fig.bbox
    for t in _texts(fig):
        e = t.get_window_extent(renderer)
        inside = (e.x0 >= box.x0 - 0.5 and e.y0 >= box.y0 - 0.5
                  and e.x1 <= box.x1 + 0.5 and e.y1 <= box.y1 + 0.5)
        assert inside, f"{t.get_text()!r} is clipped: {e} outside {box}"


def assert_ticks_apart(ax, renderer, minimum=2, which="xy"):
    """The visible tick labels of each axis of ``ax`` (``which``: "x", "y" or "xy")
    do not overlap (at least ``minimum`` of them on each axis)."""
    for axis in [{"x": ax.xaxis, "y": ax.yaxis}[a] for a in which]:
        labels = [t for t in axis.get_ticklabels() if t.get_visible() and t.get_text()]
        assert len(labels) >= minimum, [t.get_text() for t in labels]
        boxes = [t.get_window_extent(renderer) for t in labels]
        for a, b in itertools.combinations(boxes, 2):
            assert not a.overlaps(b), [t.get_text() for t in labels]


def data_points(ax, samples=8):
    """Display coordinates of what ``ax`` plots: the points of its lines (with
    ``samples`` more along each segment of a line drawn in data coordinates; reference
    lines across the axes, such as ``axhline``, only by their ends) and the offsets of
    its collections (scatter markers), those inside the axes only. Rows of (x, y)
    pixels."""
    pts = []
    for line in ax.lines:
        if not line.get_visible():
            continue
        xy = line.get_transform().transform(np.asarray(line.get_xydata(), dtype=float))
        xy = xy[np.isfinite(xy).all(axis=1)]
        drawn = line.get_linestyle() not in ("None", "", " ")
        if len(xy) > 1 and samples and drawn and line.get_transform() == ax.transData:
            s = np.linspace(0.0, 1.0, samples + 2)[:, None, None]
            xy = (xy[:-1] + s * (xy[1:] - xy[:-1])).reshape(-1, 2)
        pts.append(xy)
    for coll in ax.collections:
        offsets = np.asarray(coll.get_offsets(), dtype=float)
        if coll.get_visible() and offsets.size:
            pts.append(coll.get_offset_transform().transform(offsets))
    if not pts:
        return np.zeros((0, 2))
    xy = np.concatenate(pts)
    box = ax.get_window_extent()
    keep = ((xy[:, 0] >= box.x0) & (xy[:, 0] <= box.x1)
            & (xy[:, 1] >= box.y0) & (xy[:, 1] <= box.y1))
    return xy[keep]


def points_in(box, xy, pad=0.0):
    """Rows of ``xy`` (display pixels) inside ``box`` grown by ``pad`` pixels."""
    return xy[(xy[:, 0] > box.x0 - pad) & (xy[:, 0] < box.x1 + pad)
              & (xy[:, 1] > box.y0 - pad) & (xy[:, 1] < box.y1 + pad)]


def assert_legend_clear(ax, renderer, samples=8):
    """``ax``'s legend (if any) covers none of the points ``ax`` plots (nor the
    segments between them, sampled ``samples`` times)."""
    legend = ax.get_legend()
    if legend is None:
        return
    box = legend.get_window_extent(renderer)
    hit = points_in(box, data_points(ax, samples))
    assert hit.size == 0, f"legend of {ax.get_title()!r} covers data at {hit[:3]}"


def assert_inset_clear(ax, inset, samples=8):
    """The inset axes ``inset`` covers none of the points ``ax`` plots."""
    hit = points_in(inset.get_window_extent(), data_points(ax, samples))
    assert hit.size == 0, f"inset of {ax.get_title()!r} covers data at {hit[:3]}"


def assert_all_points_inside(ax):
    """Every point of every line of ``ax`` lies inside the axes (markers and line ends
    are not cut off by the frame)."""
    box = ax.get_window_extent()
    for line in ax.lines:
        xy = line.get_transform().transform(np.asarray(line.get_xydata(), dtype=float))
        assert np.isfinite(xy).all(), f"{line.get_label()}: a point cannot be drawn"
        inside = ((xy[:, 0] >= box.x0) & (xy[:, 0] <= box.x1)
                  & (xy[:, 1] >= box.y0) & (xy[:, 1] <= box.y1))
        assert inside.all(), f"{line.get_label()}: points outside the axes {xy[~inside]}"


def assert_annotations_apart(ax, renderer):
    """The text annotations of ``ax`` do not overlap each other."""
    texts = [t for t in ax.texts if t.get_visible() and t.get_text()]
    boxes = [t.get_window_extent(renderer) for t in texts]
    for (a, ta), (b, tb) in itertools.combinations(zip(boxes, texts, strict=True), 2):
        assert not a.overlaps(b), (ta.get_text(), tb.get_text())
