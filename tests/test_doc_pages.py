"""Every page of the documentation runs as written (tests/docwalk.py): its Python blocks
and its quick commands here, the long ones in ``make docs-walk``
(tests/walk/walk_docs.py). The tutorial has its own checks in test_tutorial.py."""

import re

import pytest

from docwalk import ROOT, blocks, looks_like_command, pages, tier, walk


def _commands(tiers):
    return [(b.where, c) for p in pages() for b in blocks(p) for c in b.commands()
            if tier(c) in tiers]


def test_every_command_block_is_labelled():
    bare = [b.where for p in pages() for b in blocks(p) if b.lang == ""
            and any(looks_like_command(ln) for ln in b.code.splitlines()[:1])]
    assert not bare, f"label these blocks bash (commands) or text (output): {bare}"


def test_commands_left_to_the_suite_are_the_suite_and_make_bench():
    """The walk never runs ``make test`` (the suite that runs the walk) nor the benchmark
    figures: every one of those must be a step of ``make bench``."""
    makefile = (ROOT / "Makefile").read_text()
    bench = makefile.split("\nbench:", 1)[1].split("\n\n", 1)[0]
    for where, cmd in _commands({"suite"}):
        script = re.match(r"python (benchmarks/\S+\.py)", cmd)
        assert cmd in ("make test", "make bench") or (script and script.group(1) in bench), (
            f"{where}: {cmd!r} is run neither by the walk nor by make bench")


def test_the_walk_covers_every_page_with_commands():
    quick = {w.split(":")[0] for w, _ in _commands({"quick"})}
    assert {"docs/multiscale.md", "docs/batch.md", "docs/cluster.md", "docs/examples.md",
            "docs/rve.md", "docs/quickstart.md"} <= quick
    full = {w.split(":")[0] for w, _ in _commands({"full"})}
    assert {"docs/stability.md", "docs/cluster.md", "docs/hostile_inputs.md"} <= full


def test_a_page_that_shows_the_wrong_output_fails(tmp_path):
    page = tmp_path / "page.md"
    page.write_text("```bash\npython -c \"print('q/p = 0.43')\"\n```\n\n"
                    "```text output\nq/p = 0.44\n  wall time  1 s\n```\n")
    (tmp_path / "run").mkdir()
    ran, failure = walk(page, {"quick"}, tmp_path / "run")
    assert len(ran) == 1 and "page.md:5" in failure and "['q/p = 0.44']" in failure


def test_vary_lets_numbers_differ_but_not_labels(tmp_path):
    cmd = ("```bash\npython -c \"print('peak 25.67 deg'); "
           "print('critical 19.38 deg')\"\n```\n\n")
    for k, (shown, ok) in enumerate((("peak 25.67 deg\ncritical 21.56 deg", True),
                      ("peak 25.60 deg\ncritical 21.56 deg", False),   # not in vary
                      ("peak 25.67 deg\ncritical angle 21.56 deg", False))):  # label
        page = tmp_path / f"page{k}.md"
        page.write_text(cmd + f"```text output vary=critical\n{shown}\n```\n")
        (tmp_path / f"run{k}").mkdir()
        ran, failure = walk(page, {"quick"}, tmp_path / f"run{k}")
        assert (failure is None) == ok, (shown, failure)


RUNNABLE = [p for p in pages() if p.name != "tutorial.md" and any(
    (b.lang == "python" and not b.norun) or any(tier(c) == "quick" for c in b.commands())
    for b in blocks(p))]


@pytest.mark.parametrize("page", RUNNABLE, ids=[p.name for p in RUNNABLE])
def test_page_runs_as_written(page, tmp_path):
    ran, failure = walk(page, {"quick"}, tmp_path)
    assert failure is None, failure
    assert ran
