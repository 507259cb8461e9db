"""Multiscale (FEMxDEM) coupling: a scikit-fem macro problem with DEM micro models.

``hmm.macro`` (the finite element problem), ``hmm.micro`` (micro models behind one
protocol), ``hmm.farm`` (serial and MPI farms of Gauss points), ``hmm.coupling``
(Newton with step cutting), ``hmm.problem`` (problem files), ``hmm.run`` (a run and the
demo), ``hmm.checkpoint``, ``hmm.io`` (fields and plots), ``hmm.experiment`` and
``hmm.batch`` (standalone RVE tests, one or many), ``hmm.cli`` (the ``hmm`` command).

:func:`read_fields` reads a run's ``fields.h5`` back as arrays with units
(:mod:`hmm.reader`).
"""

from .reader import Fields, read_fields

__all__ = ["Fields", "read_fields"]
