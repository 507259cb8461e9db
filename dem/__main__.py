"""``python -m dem``: the ``dem`` command (see :mod:`dem.cli`)."""

from .cli import main

if __name__ == "__main__":
    main()
