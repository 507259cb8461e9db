"""XDMF (version 2) side files: ParaView or VisIt read :class:`~dem.io.H5Writer` output.

The domain holds up to two temporal collections, one grid per frame in each:

``particles``
    ``Polyvertex`` grids of every particle (every body but the walls): geometry the
    centres (``XYZ`` in 3D, ``XY`` in 2D, where the reader sets z = 0), node
    attributes ``radius`` (scalar; the bounding radius of non-spheres), ``vel`` and
    ``force`` (vectors), and ``kind`` (the :class:`~dem.shapes.Shape` code) when the
    file holds bodies other than spheres, and every extra per-body scalar the writer
    was given (``fields/`` of each frame; peridynamic damage, for one). Draw them as
    sphere glyphs scaled by ``radius``; custom shapes (a user SDF, no vertices) are seen
    only this way.
``shapes``
    Only when some frame holds boxes, polygons or polyhedra: ``Triangle`` grids of
    their world-frame surfaces (``surface/`` of each frame), cell attributes ``body``
    (body index, scalar) and ``vel`` (vector). 2D shapes are flat, in the z = 0 plane.
    Frames without such shapes are left out of this collection.

The heavy data stays in the HDF5 file, referenced by a path relative to the XDMF file,
so the two files move together.

ParaView takes only 3-component arrays as vectors (glyph orientation), so in 2D each
particle vector is built as ``JOIN`` of its two columns (hyperslabs of the HDF5
dataset) and a zero column (``/xdmf/zeros``), as PyLith does; surface data is stored
with three columns already.
"""

import logging
import os
import xml.etree.ElementTree as ET

import h5py

log = logging.getLogger(__name__)

ATTRIBUTES = (("radius", "Scalar"), ("vel", "Vector"), ("force", "Vector"))


def _data_item(parent, ref, shape, number_type="Float", precision=8):
    item = ET.SubElement(parent, "DataItem", {
        "Dimensions": " ".join(str(s) for s in shape), "NumberType": number_type,
        "Precision": str(precision), "Format": "HDF"})
    item.text = ref
    return item


def _column(parent, ref, n, shape, col):
    """Hyperslab: rows ``0:n`` of column ``col`` of the dataset ``ref`` of ``shape``."""
    slab = ET.SubElement(parent, "DataItem", {
        "ItemType": "HyperSlab", "Dimensions": f"{n} 1", "Type": "HyperSlab"})
    sel = ET.SubElement(slab, "DataItem", {"Dimensions": "3 2", "Format": "XML"})
    sel.text = f"0 {col} 1 1 {n} 1"  # start, stride, count
    _data_item(slab, ref, shape)
    return slab


def _vector_2d(parent, ref, zeros_ref, n, n_zeros):
    join = ET.SubElement(parent, "DataItem", {
        "ItemType": "Function", "Function": "JOIN($0, $1, $2)", "Dimensions": f"{n} 3"})
    _column(join, ref, n, (n, 2), 0)
    _column(join, ref, n, (n, 2), 1)
    _column(join, zeros_ref, n, (n_zeros, 1), 0)
    return join


def _has_non_spheres(g):
    """Whether frame ``g`` holds particles other than spheres."""
    return int(g.attrs.get("n_particles", 0)) > int(g.attrs["n_spheres"])


def _particle_grid(series, g, name, base, ref_file, zeros, with_kind):
    n, d = g["pos"].shape
    grid = ET.SubElement(series, "Grid", {"Name": f"frame_{name}",
                                          "GridType": "Uniform"})
    ET.SubElement(grid, "Time", {"Value": repr(float(g.attrs["time"]))})
    ET.SubElement(grid, "Topology", {"TopologyType": "Polyvertex",
                                     "NumberOfElements": str(n),
                                     "NodesPerElement": "1"})
    geom = ET.SubElement(grid, "Geometry",
                         {"GeometryType": "XYZ" if d == 3 else "XY"})
    _data_item(geom, f"{base}/pos", (n, d))
    for attr, kind in ATTRIBUTES:
        a = ET.SubElement(grid, "Attribute", {
            "Name": attr, "AttributeType": kind, "Center": "Node"})
        if kind == "Vector" and d == 2 and zeros is not None:
            _vector_2d(a, f"{base}/{attr}", f"{ref_file}:/xdmf/zeros", n,
                       zeros.shape[0])
        else:
            _data_item(a, f"{base}/{attr}", g[attr].shape)
    for field in g.get("fields", {}):
        a = ET.SubElement(grid, "Attribute", {
            "Name": field, "AttributeType": "Scalar", "Center": "Node"})
        _data_item(a, f"{base}/fields/{field}", (n,))
    if with_kind and "kind" in g:
        a = ET.SubElement(grid, "Attribute", {
            "Name": "kind", "AttributeType": "Scalar", "Center": "Node"})
        _data_item(a, f"{base}/kind", (n,), "Int", 4)


def _surface_grid(series, g, name, base):
    s = g["surface"]
    n_p, n_t = s["points"].shape[0], s["cells"].shape[0]
    grid = ET.SubElement(series, "Grid", {"Name": f"shapes_{name}",
                                          "GridType": "Uniform"})
    ET.SubElement(grid, "Time", {"Value": repr(float(g.attrs["time"]))})
    topo = ET.SubElement(grid, "Topology", {"TopologyType": "Triangle",
                                            "NumberOfElements": str(n_t),
                                            "NodesPerElement": "3"})
    _data_item(topo, f"{base}/surface/cells", (n_t, 3), "Int", 4)
    geom = ET.SubElement(grid, "Geometry", {"GeometryType": "XYZ"})
    _data_item(geom, f"{base}/surface/points", (n_p, 3))
    a = ET.SubElement(grid, "Attribute", {
        "Name": "body", "AttributeType": "Scalar", "Center": "Cell"})
    _data_item(a, f"{base}/surface/body", (n_t,), "Int", 4)
    a = ET.SubElement(grid, "Attribute", {
        "Name": "vel", "AttributeType": "Vector", "Center": "Cell"})
    _data_item(a, f"{base}/surface/vel", (n_t, 3))


def write_xdmf(h5_path, xdmf_path=None):
    """Write the XDMF file describing the frames of an :class:`~dem.io.H5Writer` file.

    Parameters
    ----------
    h5_path : str or os.PathLike
        A finished HDF5 file (see :mod:`dem.io.hdf5` for its layout).
    xdmf_path : str or os.PathLike, optional
        Output path; default ``h5_path`` with the suffix ``.xdmf``.

    Returns
    -------
    str
        The path written (atomically: a temporary file renamed into place).
    """
    h5_path = os.fspath(h5_path)
    if xdmf_path is None:
        xdmf_path = os.path.splitext(h5_path)[0] + ".xdmf"
    xdmf_path = os.fspath(xdmf_path)
    ref_file = os.path.relpath(os.path.abspath(h5_path),
                               os.path.dirname(os.path.abspath(xdmf_path)))
    root = ET.Element("Xdmf", {"Version": "2.0"})
    domain = ET.SubElement(root, "Domain")
    particles = ET.SubElement(domain, "Grid", {
        "Name": "particles", "GridType": "Collection", "CollectionType": "Temporal"})
    with h5py.File(h5_path, "r") as f:
        frames = f["frames"]
        zeros = f.get("xdmf/zeros")
        names = sorted(frames, key=int)
        with_kind = any(_has_non_spheres(frames[k]) for k in names)
        for name in names:
            g = frames[name]
            if g["pos"].shape[0] == 0:
                log.debug("frame %s has no particles: left out of %s", name, xdmf_path)
                continue
            _particle_grid(particles, g, name, f"{ref_file}:/frames/{name}", ref_file,
                           zeros, with_kind)
        surfaced = [k for k in names if "surface" in frames[k]]
        if surfaced:
            shapes = ET.SubElement(domain, "Grid", {"Name": "shapes",
                                                    "GridType": "Collection",
                                                    "CollectionType": "Temporal"})
            for name in surfaced:
                _surface_grid(shapes, frames[name], name, f"{ref_file}:/frames/{name}")
    ET.indent(root)
    tmp = xdmf_path + ".tmp"
    with open(tmp, "w", encoding="utf-8") as fh:
        fh.write('<?xml version="1.0" ?>\n')
        fh.write(ET.tostring(root, encoding="unicode"))
        fh.write("\n")
    os.replace(tmp, xdmf_path)
    return xdmf_path
