"""``make docs-walk``: every page of the documentation as written, the long commands
included (full-size examples, the stability map, the Slurm script through an ``srun`` that
starts two ranks, ``make demo``). Not part of ``make test``: it takes tens of minutes."""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from docwalk import blocks, pages, tier, walk

LONG = [p for p in pages() if any(tier(c) == "full" for b in blocks(p)
                                  for c in b.commands())]


@pytest.mark.parametrize("page", LONG, ids=[p.name for p in LONG])
def test_page_runs_as_written_in_full(page, tmp_path):
    ran, failure = walk(page, {"quick", "full"}, tmp_path, timeout=3600)
    assert failure is None, failure
    assert any(tier(cmd) == "full" for _, cmd in ran)
