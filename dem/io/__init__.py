"""Output and restart: HDF5 time series with XDMF side files, checkpoints, dumps.

- :class:`H5Writer`: observer writing particle frames and contacts to HDF5, with
  XDMF 3 files (particles, contacts, walls, shapes) that ParaView and meshio open
  (:func:`write_xdmf`); :func:`read_frame` reads one frame back, :func:`read_frames`
  every frame as arrays with their units (:class:`Frames`);
- :func:`save_checkpoint` / :func:`load_checkpoint`: the full simulation state, so a
  restarted run continues bit for bit;
- :func:`write_last_good_state`: a :meth:`~dem.Simulation.on_failure` hook saving the
  last good bodies (:func:`read_bodies` reads them back).

Every file is written to ``path + ".tmp"`` and renamed into place, so a killed run
never leaves a truncated file under the final name.
"""

from .checkpoint import (
                         load_checkpoint,
                         read_bodies,
                         save_checkpoint,
                         write_bodies,
                         write_last_good_state,
)
from .hdf5 import H5Writer, read_frame
from .reader import Frames, read_frames
from .xdmf import write_xdmf

__all__ = ["Frames", "H5Writer", "load_checkpoint", "read_bodies", "read_frame",
           "read_frames", "save_checkpoint", "write_bodies", "write_last_good_state", "write_xdmf"]
