"""``python -m hmm`` runs the ``hmm`` command."""

from .cli import main

main()
