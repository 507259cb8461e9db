"""docs/tutorial.md, executed: every ``bash`` and ``python`` block, in page order, in one
scratch directory holding a copy of ``examples/``, with the venv's commands first on the
PATH. A block that fails names itself and shows its output. (The other pages:
test_doc_pages.py.)"""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "tutorial.md"
BLOCK = re.compile(r"^```(\w*)\n(.*?)^```", re.DOTALL | re.MULTILINE)


def blocks(page=PAGE):
    """(language, code, line) of every fenced block of the page."""
    text = page.read_text()
    return [(m.group(1), m.group(2), text[:m.start()].count("\n") + 1)
            for m in BLOCK.finditer(text)]


def run_blocks(page, runnable, cwd):
    """Run the page's blocks that ``runnable(lang, code)`` turns into a command (None:
    skipped), in order, in ``cwd`` holding a copy of ``examples/``; fail on the first
    that exits non-zero. Returns how many ran."""
    shutil.copytree(ROOT / "examples", cwd / "examples")
    env = dict(os.environ)
    env["PATH"] = str(Path(sys.executable).parent) + os.pathsep + env.get("PATH", "")
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env["MPLBACKEND"] = "Agg"
    ran = 0
    for lang, code, line in blocks(page):
        cmd = runnable(lang, code)
        if cmd is None:
            continue
        r = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True,
                           timeout=600, check=False)
        if r.returncode != 0:
            pytest.fail(f"docs/{page.name}:{line} ({lang or 'command'} block) exited "
                        f"{r.returncode}\n--- stdout\n{r.stdout[-3000:]}\n--- stderr\n"
                        f"{r.stderr[-3000:]}")
        ran += 1
    return ran


def test_the_page_has_runnable_blocks_of_both_kinds():
    kinds = [lang for lang, _, _ in blocks()]
    assert kinds.count("bash") >= 4 and kinds.count("python") >= 3
    assert set(kinds) <= {"bash", "python", "text"}  # text: shown, not run


def test_tutorial_runs_as_written(tmp_path):
    def runnable(lang, code):
        if lang == "text":
            return None
        return (["bash", "-euo", "pipefail", "-c", code] if lang == "bash" else
                [sys.executable, "-c", code])

    assert run_blocks(PAGE, runnable, tmp_path) == len(
        [b for b in blocks() if b[0] != "text"])
