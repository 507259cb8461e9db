"""docs/tutorial.md, executed: every ``bash`` and ``python`` block, in page order, in one
scratch directory holding a copy of ``examples/``, with the venv's commands first on
the PATH. A block that fails names itself and shows its output."""

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


def blocks():
    """(language, code, line) of every fenced block of the page."""
    text = PAGE.read_text()
    return [(m.group(1), m.group(2), text[:m.start()].count("\n") + 1)
            for m in BLOCK.finditer(text)]


def test_the_page_has_runnable_blocks_of_both_kinds():
    kinds = [lang for lang, _, _ in blocks()]
    assert kinds.count("bash") >= 4 and kinds.count("python") >= 3
    assert set(kinds) <= {"bash", "python", "text"}  # text: shown, not run


def test_tutorial_runs_as_written(tmp_path):
    shutil.copytree(ROOT / "examples", tmp_path / "examples")
    env = dict(os.environ)
    env["PATH"] = str(Path(sys.executable).parent) + os.pathsep + env.get("PATH", "")
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env["MPLBACKEND"] = "Agg"
    for lang, code, line in blocks():
        if lang == "text":
            continue
        cmd = ["bash", "-euo", "pipefail", "-c", code] if lang == "bash" else \
              [sys.executable, "-c", code]
        r = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True,
                           timeout=600, check=False)
        if r.returncode != 0:
            pytest.fail(f"docs/tutorial.md:{line} ({lang} block) exited {r.returncode}\n"
                        f"--- stdout\n{r.stdout[-3000:]}\n--- stderr\n{r.stderr[-3000:]}")
