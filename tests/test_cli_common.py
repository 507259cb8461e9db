"""One command line: ``--version`` on ``dem`` and ``hmm``, and ``-o/--output`` and
``--overwrite`` with the same meaning on every command that writes files, the particle
demo (``python -m dem.demo``) included."""

import argparse
from importlib.metadata import version

import pytest

from dem import cli as dem_cli
from dem import demo
from hmm import cli as hmm_cli


def _commands():
    """``(name, parser)`` of every command that writes files."""
    out = [("python -m dem.demo", demo._parser())]
    for prog, parser in (("dem", dem_cli._parser()), ("hmm", hmm_cli._parser())):
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        out += [(f"{prog} {name}", p) for name, p in sub.choices.items()]
    return out


@pytest.mark.parametrize("main, prog", [(dem_cli.main, "dem"), (hmm_cli.main, "hmm"),
                                        (demo.main, "dem")])
def test_version_is_one_line_from_the_package_metadata(main, prog, capsys):
    with pytest.raises(SystemExit) as end:
        main(["--version"])
    assert end.value.code == 0
    assert capsys.readouterr().out == f"{prog} {version('femxdem')}\n"


def test_every_command_takes_output_and_overwrite():
    names = []
    for name, parser in _commands():
        names.append(name)
        opts = {s: a for a in parser._actions for s in a.option_strings}
        assert opts["-o"] is opts["--output"], name
        assert opts["--output"].dest == "output", name
        assert opts["--overwrite"].default is False, name
    assert {"dem run", "hmm demo", "hmm run", "hmm rve", "hmm batch",
            "python -m dem.demo"} <= set(names)


@pytest.mark.parametrize("flag", ["-o", "--output", "--out"])
def test_the_demo_refuses_existing_output(tmp_path, capsys, flag):
    """An existing file of the demo's is left alone without --overwrite: exit 2, one
    line naming it (--out, the old spelling, still works and says it is
    deprecated)."""
    old = tmp_path / "pour.png"
    old.write_bytes(b"a figure of an earlier run")
    assert demo.main([flag, str(tmp_path), "--n", "4"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("python -m dem.demo: error: output file ")
    assert str(old) in err[-1] and "--overwrite" in err[-1]
    assert ("deprecated" in err[0]) == (flag == "--out") and len(err) == 1 + (flag == "--out")
    assert old.read_bytes() == b"a figure of an earlier run"


def test_the_demo_replaces_its_output_with_overwrite(tmp_path, capsys):
    (tmp_path / "pour.h5").write_bytes(b"not HDF5")
    args = ["-o", str(tmp_path), "--n", "4", "--t-max", "0.02"]
    assert demo.main(args + ["--overwrite"]) == 0
    assert (tmp_path / "pour.h5").read_bytes()[:4] == b"\x89HDF"
    assert (tmp_path / "pour.png").stat().st_size > 0
    assert demo.main(args) == 2  # now its own output exists
    assert "pour.h5 exists" in capsys.readouterr().err
