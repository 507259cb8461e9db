"""XDMF (version 2) side files: ParaView or VisIt read :class:`~dem.io.H5Writer` output.

The XDMF file is a temporal collection of ``Polyvertex`` grids, one per frame, whose
geometry is the sphere positions (``XYZ`` in 3D, ``XY`` in 2D, where the reader sets
z = 0) and whose node attributes are ``radius`` (scalar), ``vel`` and ``force``
(vectors). The heavy data stays in the HDF5 file, referenced by a path relative to the
XDMF file, so the two files move together.

ParaView takes only 3-component arrays as vectors (glyph orientation), so in 2D each
vector is built as ``JOIN`` of its two columns (hyperslabs of the HDF5 dataset) and a
zero column (``/xdmf/zeros``), as PyLith does.
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
    series = ET.SubElement(domain, "Grid", {
        "Name": "particles", "GridType": "Collection", "CollectionType": "Temporal"})
    with h5py.File(h5_path, "r") as f:
        frames = f["frames"]
        zeros = f.get("xdmf/zeros")
        for name in sorted(frames, key=int):
            g = frames[name]
            n, d = g["pos"].shape
            if n == 0:
                log.debug("frame %s has no spheres: left out of %s", name, xdmf_path)
                continue
            grid = ET.SubElement(series, "Grid", {"Name": f"frame_{name}",
                                                  "GridType": "Uniform"})
            ET.SubElement(grid, "Time", {"Value": repr(float(g.attrs["time"]))})
            ET.SubElement(grid, "Topology", {
                "TopologyType": "Polyvertex", "NumberOfElements": str(n),
                "NodesPerElement": "1"})
            geom = ET.SubElement(grid, "Geometry",
                                 {"GeometryType": "XYZ" if d == 3 else "XY"})
            base = f"{ref_file}:/frames/{name}"
            _data_item(geom, f"{base}/pos", (n, d))
            for attr, kind in ATTRIBUTES:
                a = ET.SubElement(grid, "Attribute", {
                    "Name": attr, "AttributeType": kind, "Center": "Node"})
                shape = g[attr].shape
                if kind == "Vector" and d == 2 and zeros is not None:
                    _vector_2d(a, f"{base}/{attr}", f"{ref_file}:/xdmf/zeros", n,
                               zeros.shape[0])
                else:
                    _data_item(a, f"{base}/{attr}", shape)
    ET.indent(root)
    tmp = xdmf_path + ".tmp"
    with open(tmp, "w", encoding="utf-8") as fh:
        fh.write('<?xml version="1.0" ?>\n')
        fh.write(ET.tostring(root, encoding="unicode"))
        fh.write("\n")
    os.replace(tmp, xdmf_path)
    return xdmf_path
