"""Checks a dry run makes of a run's outputs, without writing anything.

A dry run (``--dry-run`` of ``dem run``, ``hmm run``, ``hmm rve``, ``hmm batch``)
refuses what the real run would refuse about its outputs: an existing output file
without ``--overwrite``, an output that is a directory, and a directory that cannot
be made or written into. Nothing is created, and nothing that exists is opened for
writing.
"""

import os
from pathlib import Path

__all__ = ["check_new_files", "check_writable_dir", "work_line"]


def check_writable_dir(directory):
    """Raise OSError (one line, naming the path) if ``directory`` cannot be made or
    written into (a read-only filesystem, a file in its place or on its path, no
    write permission); make nothing."""
    directory = Path(directory)
    if directory.exists() and not directory.is_dir():
        raise NotADirectoryError(f"output directory {directory} is a file, not a "
                                 f"directory; choose another with --output")
    base = directory
    while not base.exists():  # the nearest ancestor that exists
        if base.parent == base:
            break
        base = base.parent
    if not base.is_dir():
        raise NotADirectoryError(f"output directory {directory} cannot be made: {base} "
                                 f"is a file, not a directory")
    if not os.access(base, os.W_OK | os.X_OK):
        made = "is not writable" if base == directory else "cannot be made"
        raise PermissionError(f"output directory {directory} {made}: {base} is "
                              f"read-only or not writable by this user")


def check_new_files(paths, overwrite, hint="pass --overwrite to replace it or choose "
                                            "another directory with --output"):
    """Raise OSError (one line) if one of ``paths`` is a directory, or exists while
    ``overwrite`` is False; then :func:`check_writable_dir` on their directories."""
    for path in map(Path, paths):
        if path.is_dir():
            raise IsADirectoryError(f"{path} is a directory, not an output file: remove "
                                    f"it or choose another directory with --output")
        if path.exists() and not overwrite:
            raise FileExistsError(f"output file {path} exists; {hint}")
    for directory in dict.fromkeys(Path(p).parent for p in paths):
        check_writable_dir(directory)


def work_line(n_particles, n_steps):
    """The work of a run as particle-steps, the measure its time is proportional to.

    >>> work_line(300, 1000)
    'work 3e+05 particle-steps'
    """
    return f"work {n_particles * n_steps:.3g} particle-steps"
