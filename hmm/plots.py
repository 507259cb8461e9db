"""The figures of a multiscale run, as matplotlib figures (:mod:`hmm.io` saves them).

``load_displacement_figure``
    The reaction of each driven boundary in its driven component against the
    boundary's displacement there (``load_displacement.png``).
``fields_figure``
    The last frame's deviatoric strain and share of Gauss points running DEM (or
    void ratio) on the mesh of a 2D run (``deviatoric_strain.png``).
``slices_figure``
    A cell field of a 3D run on three mid-planes (``deviatoric_strain.png`` in 3D).

Each function builds a :class:`matplotlib.figure.Figure` without pyplot (no global
state), with labelled axes in sensible units, labelled colour bars and no legend over
the data; the tests read the labels back from the figure's objects.
"""

import numpy as np

_AXES = "xyz"


def scaled_unit(values, unit, prefixes=(("M", 1e6), ("k", 1e3), ("", 1.0))):
    """``(factor, label)`` that show ``values`` [``unit``] with at most 3 or 4 digits
    before the point: the largest prefix not above their largest magnitude.

    >>> scaled_unit([0.0, 1.2e4], "N/m")
    (0.001, 'kN/m')
    >>> scaled_unit([0.0, 350.0], "N")
    (1.0, 'N')
    """
    top = float(np.nanmax(np.abs(values))) if np.size(values) else 0.0
    for prefix, size in prefixes:
        if top >= size:
            return 1.0 / size, prefix + unit
    return 1.0 / prefixes[-1][1], prefixes[-1][0] + unit


def length_unit(values):
    """``(factor, label)`` for displacements or coordinates [m]: mm from 1 µm to 1 m,
    µm below, m above.

    >>> length_unit([0.0, 8e-4])
    (1000.0, 'mm')
    """
    top = float(np.nanmax(np.abs(values))) if np.size(values) else 0.0
    if top >= 1.0:
        return 1.0, "m"
    if 0.0 < top < 1e-3 * 1e-3:
        return 1e6, "µm"
    return 1e3, "mm"


def load_displacement_figure(curve, driven, dim):
    """The load-displacement figure of a run.

    Parameters
    ----------
    curve : dict
        ``displacement/<boundary>`` and ``force/<boundary>``, (n_steps + 1, d) each,
        [m] and [N/m in 2D, N in 3D] (the ``/curve`` of ``fields.h5``).
    driven : sequence of (str, int)
        ``(boundary, component)`` of every prescribed non-zero displacement: one
        curve each, the boundary's reaction in that component against its mean
        displacement there, both along the direction it moves (``-y`` for a top
        pushed down), so that the curve rises from the origin.
    dim : int
        2 (forces per unit thickness, N/m) or 3 (N).

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    fig = Figure(figsize=(5.5, 4), layout="constrained")
    ax = fig.subplots()
    series = []
    for b, a in driven:
        u = np.asarray(curve.get(f"displacement/{b}", ()), dtype=float)
        f = np.asarray(curve.get(f"force/{b}", ()), dtype=float)
        if u.ndim != 2 or u.shape[0] == 0 or not np.any(u[:, a] != 0.0):
            continue  # nothing moved: a vertical line would say nothing
        sign = -1.0 if u[-1, a] < 0.0 else 1.0  # plot shortening as positive
        series.append((b, f"{'-' if sign < 0 else '+'}{_AXES[a]}", sign * u[:, a],
                       sign * f[:, a]))
    base = "N/m" if dim == 2 else "N"
    fu, ulabel = length_unit([s[2] for s in series] or [0.0])
    ff, flabel = scaled_unit(np.concatenate([s[3] for s in series]) if series else [],
                             base)
    for b, direction, u, f in series:
        ax.plot(fu * u, ff * f, "o-", ms=3, label=f"{b} ({direction})")
    if len(series) == 1:
        b, direction = series[0][:2]
        ax.set_xlabel(f"displacement of {b} in {direction} [{ulabel}]")
        ax.set_ylabel(f"reaction on {b} in {direction} [{flabel}]")
    else:
        ax.set_xlabel(f"prescribed displacement [{ulabel}] (positive: into the body)")
        ax.set_ylabel(f"reaction in the driven direction [{flabel}]")
    if dim == 2:
        ax.set_title("per metre of thickness (plane strain)", fontsize=9)
    ax.xaxis.set_major_locator(MaxNLocator(nbins=6, steps=[1, 2, 2.5, 5, 10]))
    ax.yaxis.set_major_locator(MaxNLocator(nbins=6, steps=[1, 2, 2.5, 5, 10]))
    ax.grid(alpha=0.3)
    if len(series) > 1:
        ax.legend(loc="best", framealpha=0.8)
    return fig


def _limits(values, fixed):
    """Colour limits: ``fixed``, or the data's, widened around a uniform field (a
    colour bar with an offset of 1e-16 says nothing)."""
    if fixed != (None, None):
        return fixed
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return 0.0, 1.0
    lo, hi = float(v.min()), float(v.max())
    if hi - lo <= 1e-6 * max(abs(lo), abs(hi)):
        pad = max(0.05 * abs(hi), 1e-12)
        return lo - pad, hi + pad
    return lo, hi


def fields_figure(points, cells, panels, title):
    """Cell fields of a 2D mesh, one panel each.

    Parameters
    ----------
    points : (n_vertices, 2) array
        Vertex coordinates to draw [m] (deformed, or displaced by a scale factor).
    cells : (n_cells, k) int array
        Corner vertices of each cell, in order around it.
    panels : sequence of (values, label, cmap, (lo, hi))
        ``values`` (n_cells,) in the unit that ``label`` names (the colour bar's
        label), a matplotlib colour map, and fixed colour limits or (None, None).
    title : str
        The figure's title (what the mesh shows).

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.collections import PolyCollection
    from matplotlib.figure import Figure

    pts = np.asarray(points, dtype=float)
    scale, unit = length_unit(pts)
    polys = scale * pts[np.asarray(cells)]
    fig = Figure(figsize=(4.2 * len(panels), 5), layout="constrained")
    axs = np.atleast_1d(fig.subplots(1, len(panels)))
    for ax, (val, label, cmap, lim) in zip(axs, panels, strict=True):
        pc = PolyCollection(polys, array=np.asarray(val, dtype=float), cmap=cmap,
                            edgecolors="k", linewidths=0.3)
        pc.set_clim(*_limits(val, lim))
        ax.add_collection(pc)
        ax.autoscale()
        ax.set_aspect("equal")
        ax.set_xlabel(f"x [{unit}]")
        ax.set_ylabel(f"y [{unit}]")
        bar = fig.colorbar(pc, ax=ax, shrink=0.8, label=label)
        bar.formatter.set_useOffset(False)
        bar.update_ticks()
    fig.suptitle(title, fontsize=10)
    return fig


#: corner pairs of the edges of a hexahedron (VTK vertex order) and of a tetrahedron
_EDGES = {8: ((0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4),
              (1, 5), (2, 6), (3, 7)),
          4: ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))}


def slice_polygons(points, cells, axis, at):
    """The cut of a 3D mesh of straight-edged hexahedra (corners in VTK order) or
    tetrahedra by the plane ``x[axis] = at``.

    Returns the polygons, each (k, 2) in the two other coordinates (in increasing
    axis order) with its corners in order around it, and the indices of the cells
    they cut. A vertex on the plane counts as beyond it, so a face lying in the plane
    is drawn once, by the cell before it.
    """
    pts = np.asarray(points, dtype=float)
    cells = np.asarray(cells)
    keep = [a for a in range(3) if a != axis]
    side = pts[:, axis] - at
    edges = _EDGES[cells.shape[1]]
    polys, cut_cells = [], []
    for c, cell in enumerate(cells):
        cut = []
        for i, j in edges:
            si, sj = side[cell[i]], side[cell[j]]
            if (si < 0.0) != (sj < 0.0):
                pi, pj = pts[cell[i], keep], pts[cell[j], keep]
                cut.append(pi + si / (si - sj) * (pj - pi))
        if len(cut) >= 3:
            q = np.array(cut)
            mid = q.mean(axis=0)
            polys.append(q[np.argsort(np.arctan2(q[:, 1] - mid[1], q[:, 0] - mid[0]))])
            cut_cells.append(c)
    return polys, np.array(cut_cells, dtype=np.int64)


def slices_figure(points, cells, values, label, title, cmap="viridis"):
    """A cell field of a 3D mesh on three planes through the middle of its bounding
    box (through the cell centre nearest the middle along each axis): normal to x
    (drawn z across, y up), to z (x across, y up) and to y (x across, z up), with one
    colour scale (:func:`slice_polygons`).

    Parameters
    ----------
    points : (n_vertices, 3) array
        Vertex coordinates to draw [m] (deformed, or displaced by a scale factor).
    cells : (n_cells, 8 or 4) int array
        Hexahedron corners in VTK order, or tetrahedron corners.
    values : (n_cells,) array
        The field, in the unit ``label`` names.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.collections import PolyCollection
    from matplotlib.figure import Figure

    pts = np.asarray(points, dtype=float)
    scale, unit = length_unit(pts)
    mid = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    # through the cell centres nearest the middle: a structured mesh puts faces on the
    # mid-planes themselves, and a deformed face crosses a plane laid along it
    centres = pts[np.asarray(cells)].mean(axis=1)
    at = centres[np.argmin(np.abs(centres - mid), axis=0), [0, 1, 2]]
    val = np.asarray(values, dtype=float)
    lim = _limits(val, (None, None))
    fig = Figure(figsize=(12.5, 5), layout="constrained")
    axs = fig.subplots(1, 3)
    for ax, (axis, across, up) in zip(axs, ((0, 2, 1), (2, 0, 1), (1, 0, 2)),
                                      strict=True):
        polys, cut = slice_polygons(pts, cells, axis, at[axis])
        keep = [a for a in range(3) if a != axis]
        order = [keep.index(across), keep.index(up)]
        pc = PolyCollection([scale * q[:, order] for q in polys], array=val[cut],
                            cmap=cmap, edgecolors="k", linewidths=0.3)
        pc.set_clim(*lim)
        ax.add_collection(pc)
        ax.autoscale()
        ax.set_aspect("equal")
        ax.set_xlabel(f"{_AXES[across]} [{unit}]")
        ax.set_ylabel(f"{_AXES[up]} [{unit}]")
        ax.set_title(f"{_AXES[axis]} = {scale * at[axis]:.3g} {unit}", fontsize=10)
    bar = fig.colorbar(pc, ax=axs, shrink=0.8, label=label)
    bar.formatter.set_useOffset(False)
    bar.update_ticks()
    fig.suptitle(title, fontsize=10)
    return fig
