"""``make docs-walk``: ParaView opens what the project writes.

Runs the pour scene (``dem run``, contacts on) and the multiscale biaxial example
(``hmm run``, finite kinematics: the mesh moves), then ParaView's ``pvpython`` on
tests/walk/paraview_check.py: both ParaView readers (Xdmf3 and the legacy one) must load
every array of the particle, contact and field files, and the force chains and the
deformed mesh are rendered (under ``xvfb-run`` where there is no display). Skipped,
and said so, where ``pvpython`` is not installed. ``DOCS_FIGURES=1`` copies the two
pictures into docs/figures/ (``force_chains.png``, ``deformed_mesh.png``).
"""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CHECK = Path(__file__).with_name("paraview_check.py")

#: the arrays each reader must show, per file (point arrays | cell arrays)
EXPECTED = {
    "pour.xdmf": ({"id", "kind", "radius", "vel", "force", "ang_vel", "quat",
                   "position"}, set()),
    "pour_contacts.xdmf": ({"position"}, {"normal_force", "tangential_force", "force",
                                          "normal", "overlap", "i", "j"}),
    "fields.xdmf": ({"displacement"}, {"stress_xx", "stress_yy", "stress_xy",
                                       "pressure", "deviatoric_strain", "void_ratio",
                                       "coordination"}),
}


def _run(args, cwd):
    env = dict(os.environ, PYTHONPATH=str(ROOT), MPLBACKEND="Agg")
    p = subprocess.run([sys.executable, "-m", *args], cwd=cwd, env=env,
                       capture_output=True, text=True, timeout=3600)
    assert p.returncode == 0, p.stderr[-2000:]


def test_paraview_opens_every_output(tmp_path):
    pvpython = shutil.which("pvpython")
    if pvpython is None:
        pytest.skip("pvpython (ParaView) is not installed: the ParaView check is skipped")
    _run(["dem", "run", str(ROOT / "examples" / "scenes" / "pour.toml"), "-o",
          str(tmp_path / "pour"), "--no-progress"], tmp_path)
    _run(["hmm", "run", str(ROOT / "examples" / "biaxial.toml"), "-o",
          str(tmp_path / "biaxial"), "--no-progress"], tmp_path)
    files = [tmp_path / "pour" / "pour.xdmf", tmp_path / "pour" / "pour_contacts.xdmf",
             tmp_path / "biaxial" / "fields.xdmf"]
    cmd = [pvpython, str(CHECK), str(tmp_path), *map(str, files)]
    if not os.environ.get("DISPLAY"):
        xvfb = shutil.which("xvfb-run")
        cmd = [xvfb, "-a", "-s", "-screen 0 1280x1024x24", *cmd] if xvfb else \
            [*cmd, "--no-render"]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
    assert p.returncode == 0, p.stderr[-2000:]
    lines = re.findall(r"^(\S+) (Xdmf3|legacy): (\d+) points, (\d+) cells; point arrays "
                       r"(\S*); cell arrays (\S*)$", p.stdout, re.M)
    seen = {(name, reader) for name, reader, *_ in lines}
    assert seen == {(f, r) for f in EXPECTED for r in ("Xdmf3", "legacy")}, p.stdout
    for name, _, n_points, n_cells, point, cell in lines:
        want_point, want_cell = EXPECTED[name]
        assert int(n_points) > 0 and int(n_cells) > 0
        assert want_point <= set(point.split(",")), (name, point)
        assert want_cell <= set(cell.split(",")), (name, cell)
    if "--no-render" in cmd:
        pytest.skip("no display and no xvfb-run: the readers were checked, nothing drawn")
    for picture in ("force_chains.png", "deformed_mesh.png"):
        data = (tmp_path / picture).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000
        if os.environ.get("DOCS_FIGURES") == "1":
            shutil.copy(tmp_path / picture, ROOT / "docs" / "figures" / picture)
