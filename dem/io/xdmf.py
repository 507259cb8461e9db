"""XDMF 3 side files: ParaView (both XDMF readers) and meshio read :class:`~dem.io.H5Writer`
output.

One HDF5 file gets up to five XDMF files, each a temporal collection with one grid per
frame (``run.h5`` -> ``run.xdmf``, ``run_shapes.xdmf``, ``run_contacts.xdmf``,
``run_walls.xdmf``, ``run_meshes.xdmf``; see :func:`xdmf_files`). One collection per
file because meshio's ``TimeSeriesReader`` reads a single collection:

particles (``run.xdmf``)
    ``Polyvertex`` grids of every particle (every body but the walls): points the
    centres, node attributes ``id`` (body index), ``kind`` (the
    :class:`~dem.shapes.Shape` code), ``radius`` [m] (the bounding radius of
    non-spheres), ``vel`` [m/s], ``force`` [N], ``ang_vel`` [rad/s] (a 3-vector in
    3D, a scalar in 2D), ``quat`` (orientation, a quaternion (w, x, y, z); in 2D
    about z), ``angle`` [rad] (2D only) and every extra per-body scalar the writer was
    given (``fields/`` of each frame; peridynamic damage, for one). Draw them as glyphs
    scaled by ``radius`` and oriented by ``quat``; custom shapes (a user SDF, no
    vertices) are seen only this way.
shapes (``run_shapes.xdmf``)
    Only when some frame holds boxes, polygons or polyhedra: ``Triangle`` grids of
    their world-frame surfaces (``surface/`` of each frame), cell attributes ``body``
    (body index) and ``vel`` [m/s]. 2D shapes are flat, in the z = 0 plane.
contacts (``run_contacts.xdmf``)
    Only when contacts were written: ``Polyline`` grids, one line per touching
    contact from the centre of ``i`` to the centre of ``j`` (a wall contact: to the
    contact point), cell attributes ``normal_force`` [N] (> 0 pushes apart),
    ``tangential_force`` [N], ``force`` [N] (on ``j``), ``normal``, ``overlap`` [m],
    ``i`` and ``j``. Coloured and scaled by ``normal_force`` they show force chains.
walls (``run_walls.xdmf``)
    Only when the scene has plane walls: each plane as a square (3D) or a segment (2D)
    around the particles, cell attributes ``id`` (body index) and ``normal``.
meshes (``run_meshes.xdmf``)
    Only when the scene has mesh walls (:class:`dem.MeshWall`): their triangles where
    they are at each frame (``meshes/`` of each frame), cell attributes ``wall`` (the
    wall's index in ``walls=[...]``) and ``normal``.

Every grid also carries its points as the node attribute ``position`` [m]: meshio's
``TimeSeriesReader`` gives the points of the first grid only, and particles move (and
their number may change). Frames with nothing to draw in a collection (no particles, no
contacts) are left out of it. Every vector is stored with three components (2D files
carry zero-padded copies under ``xdmf/`` groups), every grid has explicit cells and
``XYZ`` points, and no ``Function`` or ``HyperSlab`` items are used: ParaView's default
reader (Xdmf3) skips those. The heavy data stays in the HDF5 file, referenced by a path
relative to the XDMF file, so the files move together.
"""

import logging
import os
import xml.etree.ElementTree as ET

import h5py

from .files import write_text_atomic

#: the format tag of the particle-frame files described here (written by
#: :class:`dem.io.hdf5.H5Writer`, which takes it from this module)
FORMAT = "dem.h5writer"

log = logging.getLogger(__name__)

#: the collections, each in its own file: name -> suffix added to the stem
COLLECTIONS = {"particles": "", "shapes": "_shapes", "contacts": "_contacts",
               "walls": "_walls", "meshes": "_meshes"}


def xdmf_files(xdmf_path):
    """The XDMF files of one output: ``{collection: path}``, the particles' file
    ``xdmf_path`` and its companions next to it.

    >>> xdmf_files("out/run.xdmf")["contacts"]
    'out/run_contacts.xdmf'
    """
    stem, ext = os.path.splitext(os.fspath(xdmf_path))
    return {name: f"{stem}{suffix}{ext or '.xdmf'}" for name, suffix in COLLECTIONS.items()}


def _number_type(dtype):
    kind = {"i": "Int", "u": "UInt", "f": "Float"}[dtype.kind]
    return kind, str(dtype.itemsize)


class _Grid:
    """One uniform grid of a temporal collection, its items referring to the
    datasets of one HDF5 file."""

    def __init__(self, series, name, time, h5, ref_file):
        self.h5, self.ref_file = h5, ref_file
        self.grid = ET.SubElement(series, "Grid", {"Name": name, "GridType": "Uniform"})
        ET.SubElement(self.grid, "Time", {"Value": repr(float(time))})

    def item(self, parent, path):
        """A DataItem for the whole dataset ``path`` of the HDF5 file."""
        dset = self.h5[path]
        kind, precision = _number_type(dset.dtype)
        it = ET.SubElement(parent, "DataItem", {
            "Dimensions": " ".join(str(s) for s in dset.shape), "NumberType": kind,
            "Precision": precision, "Format": "HDF"})
        it.text = f"{self.ref_file}:{path}"

    def mesh(self, topology, cells, points):
        """Cells and points; the points also as the node attribute ``position``, which
        meshio's ``TimeSeriesReader`` reads per step (its points are the first
        grid's)."""
        n, k = self.h5[cells].shape
        topo = ET.SubElement(self.grid, "Topology", {
            "TopologyType": topology, "NumberOfElements": str(n),
            "NodesPerElement": str(k)})
        self.item(topo, cells)
        self.item(ET.SubElement(self.grid, "Geometry", {"GeometryType": "XYZ"}), points)
        self.attribute("position", points)

    def attribute(self, name, path, center="Node"):
        """An attribute whose type follows the dataset's shape: (n,) or (n, 1)
        scalar, (n, 3) vector, anything else a matrix (a quaternion)."""
        shape = self.h5[path].shape
        if len(shape) == 1 or shape[1] == 1:
            kind = "Scalar"
        else:
            kind = "Vector" if shape[1] == 3 else "Matrix"
        a = ET.SubElement(self.grid, "Attribute", {
            "Name": name, "AttributeType": kind, "Center": center})
        self.item(a, path)


def _particles(series, g, name, base, h5, ref_file):
    d = g["pos"].shape[1]
    padded = f"{base}/xdmf" if d == 2 else base  # 3-vectors: padded copies in 2D
    grid = _Grid(series, f"frame_{name}", g.attrs["time"], h5, ref_file)
    grid.mesh("Polyvertex", f"{base}/xdmf/vertex", f"{padded}/pos")
    for attr in ("id", "kind", "radius"):
        grid.attribute(attr, f"{base}/{attr}")
    for attr in ("vel", "force"):
        grid.attribute(attr, f"{padded}/{attr}")
    grid.attribute("ang_vel", f"{base}/ang_vel")
    grid.attribute("quat", f"{padded}/quat" if d == 2 else f"{base}/rot")
    if d == 2:
        grid.attribute("angle", f"{base}/rot")
    for field in g.get("fields", {}):
        grid.attribute(field, f"{base}/fields/{field}")


def _shapes(series, g, name, base, h5, ref_file):
    grid = _Grid(series, f"shapes_{name}", g.attrs["time"], h5, ref_file)
    grid.mesh("Triangle", f"{base}/surface/cells", f"{base}/surface/points")
    for attr in ("body", "vel"):
        grid.attribute(attr, f"{base}/surface/{attr}", "Cell")


def _contacts(series, g, name, base, h5, ref_file):
    c = f"{base}/contacts"
    padded = f"{c}/xdmf" if g["pos"].shape[1] == 2 else c
    grid = _Grid(series, f"contacts_{name}", g.attrs["time"], h5, ref_file)
    grid.mesh("Polyline", f"{c}/xdmf/lines", f"{c}/xdmf/points")
    for attr in ("normal_force", "overlap", "i", "j"):
        grid.attribute(attr, f"{c}/{attr}", "Cell")
    for attr in ("tangential_force", "force", "normal"):
        grid.attribute(attr, f"{padded}/{attr}", "Cell")


def _walls(series, g, name, base, h5, ref_file):
    w = f"{base}/walls"
    grid = _Grid(series, f"walls_{name}", g.attrs["time"], h5, ref_file)
    topology = "Quadrilateral" if g["pos"].shape[1] == 3 else "Polyline"
    grid.mesh(topology, f"{w}/xdmf/cells", f"{w}/xdmf/points")
    grid.attribute("id", f"{w}/id", "Cell")
    grid.attribute("normal", f"{w}/xdmf/normal", "Cell")


def _meshes(series, g, name, base, h5, ref_file):
    m = f"{base}/meshes"
    grid = _Grid(series, f"meshes_{name}", g.attrs["time"], h5, ref_file)
    grid.mesh("Triangle", f"{m}/cells", f"{m}/points")
    grid.attribute("wall", f"{m}/wall", "Cell")
    grid.attribute("normal", f"{m}/normal", "Cell")


#: collection -> (frame holds something to draw, grid builder)
_BUILDERS = {
    "particles": (lambda g: g["pos"].shape[0] > 0, _particles),
    "shapes": (lambda g: "surface" in g, _shapes),
    "contacts": (lambda g: int(g.attrs.get("n_contacts", 0)) > 0
                 and "xdmf" in g.get("contacts", {}), _contacts),
    "walls": (lambda g: "xdmf" in g["walls"], _walls),
    "meshes": (lambda g: "meshes" in g, _meshes),
}


def _write(root, path):
    ET.indent(root)
    write_text_atomic(path, '<?xml version="1.0" ?>\n'
                      + ET.tostring(root, encoding="unicode") + "\n")


def write_xdmf(h5_path, xdmf_path=None):
    """Write the XDMF files describing the frames of an :class:`~dem.io.H5Writer` file.

    The particles go to ``xdmf_path``, the shapes, contacts and walls (where the file
    has any) to its companions (:func:`xdmf_files`); a companion left from an earlier
    file of that name is removed.

    Parameters
    ----------
    h5_path : str or os.PathLike
        A finished HDF5 file of format version 3 or later (see :mod:`dem.io.hdf5`).
    xdmf_path : str or os.PathLike, optional
        Output path of the particles' file; default ``h5_path`` with the suffix
        ``.xdmf``.

    Returns
    -------
    str
        The particles' path. Files are written atomically (a temporary file renamed
        into place).
    """
    h5_path = os.fspath(h5_path)
    if xdmf_path is None:
        xdmf_path = os.path.splitext(h5_path)[0] + ".xdmf"
    xdmf_path = os.fspath(xdmf_path)
    ref_file = os.path.relpath(os.path.abspath(h5_path),
                               os.path.dirname(os.path.abspath(xdmf_path)))
    paths = xdmf_files(xdmf_path)
    with h5py.File(h5_path, "r") as h5:
        version = h5.attrs.get("version", 0)
        if h5.attrs.get("format") != FORMAT or version < 3:
            raise ValueError(f"{h5_path}: not a {FORMAT} file of version 3 or later "
                             f"(format {h5.attrs.get('format')!r}, version {version})")
        frames = h5["frames"]
        names = sorted(frames, key=int)
        for coll, (has, build) in _BUILDERS.items():
            drawn = [k for k in names if has(frames[k])]
            if not drawn and coll != "particles":
                if os.path.exists(paths[coll]):
                    os.remove(paths[coll])  # describes a file that is gone
                continue
            root = ET.Element("Xdmf", {"Version": "3.0"})
            series = ET.SubElement(ET.SubElement(root, "Domain"), "Grid", {
                "Name": coll, "GridType": "Collection", "CollectionType": "Temporal"})
            for name in drawn:
                build(series, frames[name], name, f"/frames/{name}", h5, ref_file)
            _write(root, paths[coll])
            log.debug("wrote %s (%d of %d frames)", paths[coll], len(drawn), len(names))
    return xdmf_path
