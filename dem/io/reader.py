"""Particle files (:class:`~dem.io.H5Writer` output) read back as numpy arrays with
their units.

>>> import tempfile, dem
>>> from dem.io import H5Writer, read_frames
>>> b = dem.Bodies.spheres([[0.0, 0.0], [0.05, 0.0]], radius=0.01, density=2500.0)
>>> sim = dem.Simulation(b, dem.LinearSpring(kn=1e4), dt=1e-5)
>>> with tempfile.TemporaryDirectory() as tmp:
...     with H5Writer(tmp + "/run.h5", every=10) as out:
...         sim.observers.append(out)
...         sim.run(20)
...     frames = read_frames(tmp + "/run.h5")
>>> len(frames), frames["pos"].shape, frames.units["pos"], frames.time.tolist()
(2, (2, 2, 2), 'm', [0.0001, 0.0002])
"""

from dataclasses import dataclass, field

import h5py
import numpy as np

from .hdf5 import frame_name, read_bounded
from .meta import check_format, text
from .xdmf import FORMAT

#: the versions of the particle-file layout this reader knows
VERSIONS = (2, 3, 4)


@dataclass
class Frames:
    """The frames of a particle file.

    Attributes
    ----------
    path : str
    attrs : dict
        The file's root attributes: ``format``, ``version``, ``software``,
        ``config`` (the scene file's text, when the writer was given it), ``dim``,
        ``n_frames``.
    step : (n_frames,) int64
        The step of each frame.
    time : (n_frames,) float64
        [s].
    frames : list of dict
        Per frame, ``{name: array}`` of every dataset of the frame, by its path in
        the frame (``"pos"``, ``"vel"``, ``"walls/normal"``, ``"contacts/force"``,
        ``"fields/damage"``, ...); the viewers' copies (``xdmf/`` groups) are left
        out.
    frame_attrs : list of dict
        Per frame, its attributes (``step``, ``time``, ``dt``, ``n_particles``,
        ``n_contacts``, ...).
    units : dict
        ``{name: unit}`` of every name (SI; ``"1"`` for numbers without a unit).
    signs : dict
        ``{name: sign convention}`` of the names whose sign matters.

    ``frames["pos"]`` stacks a name over the frames, ``(n_frames, ...)``, where
    every frame has the same shape (a fixed number of particles; contacts come and
    go: read those frame by frame, ``frames.frames[k]["contacts/force"]``).
    """

    path: str
    attrs: dict
    step: np.ndarray
    time: np.ndarray
    frames: list
    frame_attrs: list
    units: dict = field(default_factory=dict)
    signs: dict = field(default_factory=dict)

    def __len__(self):
        return len(self.frames)

    @property
    def names(self):
        """Every dataset name of any frame, sorted."""
        return sorted({k for f in self.frames for k in f})

    def __getitem__(self, name):
        """``name`` stacked over the frames, ``(n_frames, ...)``."""
        missing = [k for k, f in enumerate(self.frames) if name not in f]
        if missing:
            raise KeyError(f"{self.path}: frame {missing[0]} has no {name!r} "
                           f"(names: {', '.join(self.names)})")
        shapes = {f[name].shape for f in self.frames}
        if len(shapes) > 1:
            raise ValueError(f"{self.path}: {name!r} changes shape between frames "
                             f"({', '.join(map(str, sorted(shapes)))}); read it frame "
                             f"by frame: .frames[k][{name!r}]")
        return np.stack([f[name] for f in self.frames])


def read_frames(path, frames=None):
    """Read a particle file written by :class:`~dem.io.H5Writer` (``dem run``).

    Parameters
    ----------
    path : str or os.PathLike
    frames : sequence of int, optional
        The frames to read (0, 1, ...; negative counts from the end); default all.

    Returns
    -------
    Frames

    Raises
    ------
    ValueError
        ``path`` is not HDF5, another kind of file (its ``format`` tag), a version
        this reader does not know, or a dataset declares more data than the file
        holds.
    """
    path = str(path)
    try:
        f = h5py.File(path, "r")
    except OSError as err:
        raise ValueError(f"{path} is not a readable HDF5 file "
                         f"({' '.join(str(err).split())})") from None
    with f:
        check_format(f, path, FORMAT, VERSIONS)
        attrs = {k: _value(v) for k, v in f.attrs.items()}
        group = f.get("frames")
        if not isinstance(group, h5py.Group):
            raise ValueError(f"{path}: no frames group")
        n = len(group)
        which = range(n) if frames is None else [k + n if k < 0 else k for k in frames]
        out = Frames(path, attrs, np.zeros(0, np.int64), np.zeros(0), [], [])
        for k in which:
            if not 0 <= k < n or frame_name(k) not in group:
                raise IndexError(f"{path} has {n} frames, no frame {k}")
            g = group[frame_name(k)]
            out.frame_attrs.append({a: _value(v) for a, v in g.attrs.items()})
            out.frames.append(_datasets(g, out))
    out.step = np.array([a.get("step", -1) for a in out.frame_attrs], np.int64)
    out.time = np.array([a.get("time", np.nan) for a in out.frame_attrs], np.float64)
    return out


def _datasets(g, out):
    """``{path: array}`` of the datasets of frame group ``g`` (not ``xdmf/``),
    their units and signs noted in ``out``."""
    data = {}

    def visit(name, obj):
        if not isinstance(obj, h5py.Dataset) or "xdmf" in name.split("/"):
            return
        data[name] = read_bounded(obj, f"{g.name}/{name}")
        if "unit" in obj.attrs:
            out.units[name] = text(obj.attrs["unit"])
        if "sign" in obj.attrs:
            out.signs[name] = text(obj.attrs["sign"])

    g.visititems(visit)
    return data


def _value(v):
    """An HDF5 attribute as a plain Python value (str, int, float) or an array."""
    v = text(v)
    if isinstance(v, np.generic):
        return v.item()
    return v
