"""Running the documentation as written.

A page's fenced blocks run in page order in one scratch directory that holds copies of
``examples/``, ``benchmarks/`` and ``tests/`` and a ``.venv`` link to the running interpreter's
environment, with that environment's commands first on the ``PATH``:

- ``python`` blocks: ``python -c`` the block;
- ``bash`` blocks: each command line (``#`` comments dropped) through
  ``bash -euo pipefail``; a block that is a script (``#!`` first, a here-document, an
  ``if``) runs whole;
- ``toml file=NAME`` (any language): written to ``NAME`` before anything runs;
- ``text output`` blocks: what the command before prints; every line but a ``wall time``
  must be a line of that command's output; ``vary=WORD,...`` lists lines (by their first
  word) whose numbers may differ from machine to machine: their label, the text before
  the first number, must be printed;
- other ``text`` and unlabelled blocks are output and pseudo-code, and ``... norun``
  blocks are fragments: shown, not run. An unlabelled block that starts with a command
  is an error (label it).

Commands are sorted into tiers by :func:`tier`: ``quick`` ones run in ``make test``,
``full`` ones only in ``make docs-walk`` (full-size examples, benchmarks that take minutes,
cluster scripts, ``make demo``, the suite's own files), and ``suite`` ones never by the
walk, because they are the suite or the benchmark collection itself (``make test``,
``make bench`` and the benchmark figures of docs/performance.md, which ``make bench``
regenerates).
"""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
BLOCK = re.compile(r"^```(\w*)([^\n]*)\n(.*?)^```", re.DOTALL | re.MULTILINE)
#: first words of a shell command (after ``VAR=value`` assignments)
COMMANDS = ("hmm", "dem", "python", "pytest", "make", "mpiexec", "srun", "export",
            "cat", "ls", "cd", ".venv/bin/", "NUMBA_", "EXAMPLES_SIZE=")
#: commands that only ``make docs-walk`` runs (minutes each, or a cluster)
FULL = (re.compile(r"EXAMPLES_SIZE=full"), re.compile(r"^#!"), re.compile(r"^make demo"),
        re.compile(r"^pytest "), re.compile(r"benchmarks/stability_map\.py"),
        re.compile(r"examples/beams_lattice\.py"))
#: commands the walk never runs: the suite and the benchmark figures themselves
SUITE = (re.compile(r"^make (test|bench)$"), re.compile(r"^python benchmarks/(?!stability)"))
#: files a page names without showing them: (page, name) -> (source in the repository,
#: {text: replacement})
SETUP = {("cluster.md", "problem.toml"): (  # a problem of the page's kind: default
    "examples/biaxial.toml",                   # output directory, checkpoints
    {'dir = "output/biaxial"': "checkpoint_every = 5"})}


class Block:
    """One fenced block: language, info-string words, code, first line on the page."""

    def __init__(self, page, lang, info, code, line):
        self.page, self.lang, self.code, self.line = page, lang, code, line
        words = info.split()
        self.norun = "norun" in words
        self.output = lang == "text" and "output" in words
        self.file = next((w[5:] for w in words if w.startswith("file=")), None)
        vary = next((w[5:] for w in words if w.startswith("vary=")), "")
        self.vary = set(filter(None, vary.split(",")))

    @property
    def where(self):
        page = (self.page.relative_to(ROOT) if self.page.is_relative_to(ROOT)
                else self.page.name)
        return f"{page}:{self.line}"

    def commands(self):
        """The block's shell commands: one per line, or the whole block for a script."""
        if self.lang != "bash" or self.norun or self.file:
            return []
        code = self.code
        if code.startswith("#!") or "<<" in code or re.search(r"^\s*if ", code, re.M):
            return [code]
        lines = [ln.split(" #")[0].strip() for ln in code.splitlines()]
        return [ln for ln in lines if ln and not ln.startswith("#")]


def blocks(page):
    """Every fenced block of ``page``."""
    text = page.read_text()
    return [Block(page, m.group(1), m.group(2), m.group(3),
                  text[:m.start()].count("\n") + 1) for m in BLOCK.finditer(text)]


def pages():
    """The pages the walk covers: README.md and docs/*.md."""
    return [ROOT / "README.md"] + sorted(DOCS.glob("*.md"))


def looks_like_command(line):
    line = line.strip()
    while re.match(r"^[A-Z_]+=\S*\s", line):
        line = line.split(None, 1)[1]
    return line.startswith(COMMANDS) and not line.startswith(("hmm batch: error",
                                                              "hmm run: error"))


def tier(cmd):
    """``quick``, ``full`` or ``suite`` for one command (see the module notes)."""
    first = cmd.strip()
    if any(p.search(first) for p in SUITE):
        return "suite"
    if any(p.search(first) for p in FULL):
        return "full"
    return "quick"


def _environment(cwd):
    env = dict(os.environ)
    bin_dir = Path(sys.executable).parent
    env["PATH"] = f"{cwd / 'bin'}{os.pathsep}{bin_dir}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env["MPLBACKEND"] = "Agg"
    env["SLURM_SUBMIT_DIR"] = str(cwd)
    return env


def scratch(cwd, page):
    """Fill ``cwd`` for ``page``: examples, benchmarks, tests, the venv link, named
    files, the Makefile and an ``srun`` that starts two ranks with the venv's
    ``mpiexec``."""
    shutil.copytree(ROOT / "examples", cwd / "examples")
    shutil.copytree(ROOT / "benchmarks", cwd / "benchmarks",
                    ignore=shutil.ignore_patterns("results", "__pycache__"))
    (cwd / "benchmarks" / "results").mkdir()
    shutil.copytree(ROOT / "tests", cwd / "tests",
                    ignore=shutil.ignore_patterns("__pycache__"))
    for name in ("Makefile", "pyproject.toml"):
        shutil.copy2(ROOT / name, cwd / name)
    (cwd / ".venv").symlink_to(Path(sys.executable).parent.parent)
    cache = os.environ.get("NUMBA_CACHE_DIR")
    if cache:
        (cwd / ".numba_cache").symlink_to(Path(cache).resolve())
    for (name, target), (source, edits) in SETUP.items():
        if name == page.name:
            text = (ROOT / source).read_text()
            for old, new in edits.items():
                assert old in text, (source, old)
                text = text.replace(old, new)
            (cwd / target).write_text(text)
    (cwd / "bin").mkdir()
    srun = cwd / "bin" / "srun"
    srun.write_text('#!/bin/bash\nwhile [[ "$1" == --* ]]; do shift; done\n'
                    f'exec "{Path(sys.executable).parent}/mpiexec" -n 2 "$@"\n')
    srun.chmod(0o755)


def _label(line):
    """The text of an output line before its first number."""
    return re.split(r"\s[-+]?\d", line.strip() + " 0", maxsplit=1)[0]


def walk(page, tiers, cwd, timeout=1800):
    """Run ``page`` as written in ``cwd``: its python blocks, its file blocks and its
    commands of the given tiers, in page order. Returns ``(ran, failure)``: the
    ``(where, command)`` pairs that ran, and None or a message naming the first that
    failed with its output."""
    scratch(cwd, page)
    env = _environment(cwd)
    ran = []
    for b in blocks(page):
        if b.file:
            (cwd / b.file).write_text(b.code)
    last = None
    for b in blocks(page):
        if b.output:
            printed = set(ln.rstrip() for ln in last.splitlines()) if last else set()
            labels = {_label(ln) for ln in printed}
            wrong = [ln for ln in b.code.splitlines() if "wall time" not in ln
                     and ln.rstrip() not in printed
                     and not (ln.split()[:1] and ln.split()[0] in b.vary
                              and _label(ln) in labels)]
            if wrong:
                return ran, (f"{b.where}: the command before does not print these lines "
                             f"of the page: {wrong}\n--- it printed\n{last}")
            continue
        if b.lang == "python" and not b.norun:
            todo = [(b.code, [sys.executable, "-c", b.code])]
        else:
            todo = [(c, ["bash", "-euo", "pipefail", "-c", c]) for c in b.commands()
                    if tier(c) in tiers]
        for shown, argv in todo:
            r = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True,
                               timeout=timeout, check=False)
            if r.returncode != 0:
                return ran, (f"{b.where} ({b.lang} block) exited {r.returncode}:\n"
                             f"{shown[:500]}\n--- stdout\n{r.stdout[-3000:]}\n"
                             f"--- stderr\n{r.stderr[-3000:]}")
            ran.append((b.where, shown))
            last = r.stdout + r.stderr
    return ran, None
