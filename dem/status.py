"""Status codes of the compiled kernels: one list for every kernel and its wrapper.

A kernel does not raise. It stops and writes a code into its ``status_out`` array (with
the bodies involved in the next entries), or returns one; its Python wrapper turns the
code into an action (rebuild the neighbour list, then resume) or into one line of
:class:`dem.SimulationError`.

The codes are the members of :class:`Status`. Kernels import the plain ``int`` names
below: numba freezes module globals at compile time, so a code is a constant of the
compiled loop. This module imports nothing of ``dem``.

The values are kept where a file records them: an ADMM contact solve
(:func:`dem.contact.detection.admm.admm_contact`) returns ``1`` when it did not
converge, as stored in ``benchmarks/results/stability_map.json``.

>>> Status(REBUILD).name
'REBUILD'
"""

from enum import IntEnum, unique

__all__ = ["CAME_APART", "NOCONVERGE", "NONFINITE", "NOT_RELAXED", "OK", "OVERLAP", "REBUILD",
           "RELAXED", "Status"]


@unique
class Status(IntEnum):
    """What stopped a kernel (``OK``: nothing did)."""

    #: the call did what it was asked
    OK = 0
    #: a contact detection (ADMM) did not converge, warm or cold
    NOCONVERGE = 1
    #: a position, velocity or force is not finite: the run blew up
    NONFINITE = 2
    #: an overlap beyond the limit: the time step is too large or the bodies too fast
    OVERLAP = 3
    #: a body moved past half the skin: rebuild the neighbour list, then resume
    REBUILD = 4
    #: a relaxation check found the unbalanced-force ratio below its tolerance
    #: (:meth:`dem.Simulation.relax`): the loop stopped early, as asked
    RELAXED = 5
    #: a relaxation check found too few contacts for its set number of checks in a
    #: row: the packing came apart (a gas, which never relaxes)
    CAME_APART = 6
    #: a drive check (:mod:`dem.contact.servo`) found its relaxation's step cap spent
    #: with the servo off target or the packing not at rest
    NOT_RELAXED = 7


OK = int(Status.OK)
NOCONVERGE = int(Status.NOCONVERGE)
NONFINITE = int(Status.NONFINITE)
OVERLAP = int(Status.OVERLAP)
REBUILD = int(Status.REBUILD)
RELAXED = int(Status.RELAXED)
CAME_APART = int(Status.CAME_APART)
NOT_RELAXED = int(Status.NOT_RELAXED)
