"""``dem run scene.toml``: valid scenes run; bad input is one line on stderr, exit 2."""

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dem.cli import main
from dem.io.scene import SCHEMA, SceneError, load_scene, schema_markdown

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "pour.toml"


# --------------------------------------------------------------------------- helpers
def base_scene():
    """Eight spheres on a 2 x 2 x 2 lattice resting on a floor; 40 steps."""
    return {
        "simulation": {"steps": 40, "gravity": [0.0, 0.0, -9.81]},
        "particles": {"generator": "lattice", "count": 8, "lo": [0.0, 0.0, 0.0],
                      "hi": [0.03, 0.03, 0.03], "radius": 0.005, "density": 2500.0},
        "walls": [{"point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0]}],
        "contact": {"law": "linear", "kn": 1.0e4, "kt": 5.0e3, "mu": 0.5,
                    "restitution": 0.5},
        "output": {"every": 20},
    }


def _value(v):
    if isinstance(v, bool):
        return str(v).lower()
    if isinstance(v, str):
        return '"' + v + '"'
    if isinstance(v, float) and not math.isfinite(v):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    return repr(v)


def to_toml(scene):
    lines = []
    for name, body in scene.items():
        tables = [(f"[[{name}]]", t) for t in body] if isinstance(body, list) else [
            (f"[{name}]", body)]
        for head, table in tables:
            lines.append(head)
            lines += [f"{k} = {_value(v)}" for k, v in table.items()]
            lines.append("")
    return "\n".join(lines)


def write_scene(tmp_path, scene, name="scene.toml"):
    path = tmp_path / name
    path.write_text(to_toml(scene) if isinstance(scene, dict) else scene)
    return path


def run_cli(args, capsys):
    """main(args) in-process; returns (exit status, stdout, stderr)."""
    with pytest.raises(SystemExit) as exc:
        main([str(a) for a in args])
    out, err = capsys.readouterr()
    return exc.value.code, out, err


def run_subprocess(args, cwd):
    env = dict(os.environ)
    env.setdefault("NUMBA_NUM_THREADS", "2")
    proc = subprocess.run([sys.executable, "-m", "dem", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, env=env, timeout=300)
    return proc.returncode, proc.stdout, proc.stderr


def assert_one_line_error(err, *fragments):
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("dem: error: ")
    assert "Traceback" not in err
    for f in fragments:
        assert f in lines[0], lines[0]


def _h5_writer_available():
    try:
        from dem.io.hdf5 import H5Writer  # noqa: F401
    except ImportError:
        return False
    return True


# --------------------------------------------------------------------------- bad input
def _set(section, key, value):
    def edit(scene, tmp_path):
        scene[section][key] = value
    return edit


def _drop(section, key):
    def edit(scene, tmp_path):
        del scene[section][key]
    return edit


def _edit_wall(**changes):
    def edit(scene, tmp_path):
        scene["walls"][0].update(changes)
    return edit


def _particle_file(scene, tmp_path, rows, name="packing.txt"):
    (tmp_path / name).write_text("# x y z r\n" + "\n".join(rows) + "\n")
    scene["particles"] = {"generator": "file", "file": name, "density": 2500.0}


def _overlapping_file(scene, tmp_path):
    """Particles 1 and 2 overlap by 2 mm; 0 touches nobody."""
    rows = ["0.02 0.02 0.01 0.005", "0.05 0.02 0.01 0.005", "0.058 0.02 0.01 0.005"]
    _particle_file(scene, tmp_path, rows)


def _missing_file(scene, tmp_path):
    scene["particles"] = {"generator": "file", "file": "missing.txt", "density": 1.0}


def _extra_section(scene, tmp_path):
    scene["material"] = {"young": 1.0}


def _drop_section(scene, tmp_path):
    del scene["contact"]


def _wall_through_particles(scene, tmp_path):
    scene["walls"].append({"point": [0.0, 0.0, 0.02], "normal": [0.0, 0.0, 1.0]})


HERTZ = {"law": "hertz_mindlin", "young": 1.0e7, "poisson": 0.3, "mu": 0.5}


def _hertz_wall(**changes):
    """The base scene with a Hertz-Mindlin law, its wall given ``changes``."""
    def edit(scene, tmp_path):
        scene["contact"] = dict(HERTZ)
        scene["walls"][0].update(changes)
    return edit


def _groups(*tables, insert_group=None):
    """The base scene's particles as group "sand" (and an [insert] of
    ``insert_group``), its law as the [[contact]] ``tables`` (pair, law kind)."""
    def edit(scene, tmp_path):
        scene["particles"]["group"] = "sand"
        if insert_group:
            scene["insert"] = {"count": 2, "rate": 100.0, "lo": [0.0, 0.0, 0.05],
                               "hi": [0.03, 0.03, 0.08], "radius": 0.005,
                               "group": insert_group}
        linear = dict(scene["contact"])
        scene["contact"] = [{**(HERTZ if kind == "hertz" else linear),
                             **({"pair": pair} if pair else {})} for pair, kind in tables]
    return edit


# case: (edit of the base scene, fragments the one error line must contain)
BAD = {
    "unknown key": (_set("particles", "radiuss", 0.01),
                    ["scene.toml: [particles] unknown key 'radiuss'", "'radius'"]),
    "unknown section": (_extra_section, ["unknown section [material]"]),
    "wrong type": (_set("particles", "density", "heavy"),
                   ["[particles] density must be a number", '"heavy"']),
    "wrong type int": (_set("simulation", "steps", 2.5),
                       ["[simulation] steps must be an integer, got 2.5"]),
    "wrong type bool": (_set("output", "contacts", 1),
                        ["[output] contacts must be true or false"]),
    "wrong vector length": (_set("simulation", "gravity", [0.0, -9.81]),
                            ["[simulation] gravity must be an array of 3 numbers"]),
    "missing required key": (_drop("contact", "kn"),
                             ["[contact] missing required key 'kn'"]),
    "missing section": (_drop_section, ["missing required section [contact]"]),
    "negative radius": (_set("particles", "radius", -0.01),
                        ["scene.toml: [particles] radius must be > 0, got -0.01"]),
    "radius range reversed": (_set("particles", "radius", [0.005, 0.004]),
                              ["[particles] radius", "min <= max"]),
    "friction < 0": (_set("contact", "mu", -0.1),
                     ["[contact] mu must be >= 0, got -0.1"]),
    "restitution 1.5": (_set("contact", "restitution", 1.5),
                        ["[contact] restitution must be in (0, 1], got 1.5"]),
    "nan": (_set("contact", "kn", float("nan")),
            ["[contact] kn must be finite, got nan"]),
    "nan in vector": (_set("simulation", "gravity", [0.0, 0.0, float("nan")]),
                      ["[simulation] gravity[2] must be finite"]),
    "dt zero": (_set("simulation", "dt", 0.0), ["[simulation] dt must be > 0, got 0"]),
    "dt negative": (_set("simulation", "dt", -1e-5), ["[simulation] dt must be > 0"]),
    "dt above stable": (_set("simulation", "dt", 1.0),
                        ["[simulation] dt = 1 s exceeds the stable time step dt_stable"]),
    "bad choice": (_set("contact", "law", "hooke"),
                   ['[contact] law must be "linear", "hertz_mindlin" or "hertz_sjkr", '
                    'got "hooke"']),
    "key of another law": (_set("contact", "young", 1e7),
                           ['[contact] young is not used with law = "linear"']),
    "wall normal zero": (_edit_wall(normal=[0.0, 0.0, 0.0]),
                         ["[[walls]] #1 normal must be a non-zero vector"]),
    "wall unknown key": (_edit_wall(speed=1.0), ["[[walls]] #1 unknown key 'speed'"]),
    "particle behind wall": (_wall_through_particles,
                             ["[[walls]] #2 particle 0", "overlaps the wall"]),
    "lattice too small": (_set("particles", "count", 9),
                          ["[particles] count = 9 exceeds the 8 lattice sites"]),
    "overlapping particles from file": (
        _overlapping_file,
        ["[particles] file", "particles 1 and 2", "overlap by 0.002 m"]),
    "missing particle file": (_missing_file,
                              ["[particles] file: cannot read", "missing.txt"]),
    "wall key of another law": (_hertz_wall(kn=1e4), [
        "[[walls]] #1 kn is not used with the hertz_mindlin law of particle-wall contacts"]),
    "wall rigid with a linear law": (_edit_wall(rigid=True),
                                     ["[[walls]] #1 rigid is not used with the linear law"]),
    "wall young negative": (_hertz_wall(young=-1.0),
                            ["[[walls]] #1 young must be > 0, got -1"]),
    "wall mu nan": (_edit_wall(mu=float("nan")), ["[[walls]] #1 mu must be finite, got nan"]),
    "wall poisson 0.5": (_hertz_wall(poisson=0.5),
                         ["[[walls]] #1 poisson must be in [0, 0.5), got 0.5"]),
    "wall rigid and young": (_hertz_wall(rigid=True, young=1e9),
                             ["[[walls]] #1 rigid = true and young exclude each other"]),
    "pair of an unknown group": (_groups((["sand", "sand"], "linear"),
                                         (["sand", "steel"], "linear")),
                                 ['[[contact]] #2 pair names the group "steel", which no '
                                  '[particles] or [insert] defines']),
    "group pair with no law": (_groups((["sand", "sand"], "linear")),
                               ['[[contact]] no law for the group pair ["sand", "walls"]']),
    "pair missing among several": (_groups((["sand", "sand"], "linear"), (None, "linear")),
                                   ["[[contact]] #2 missing required key 'pair'"]),
    "pair repeated": (_groups((["sand", "walls"], "linear"), (["walls", "sand"], "linear")),
                      ['[[contact]] #2 pair = ["walls", "sand"] repeats that of #1']),
    "law kinds mixed in a bucket": (
        _groups((["sand", "sand"], "linear"), (["sand", "gravel"], "hertz"),
                (["gravel", "gravel"], "linear"), (["sand", "walls"], "linear"),
                (["gravel", "walls"], "linear"), insert_group="gravel"),
        ['[[contact]] #2 law = "hertz_mindlin" differs from law = "linear" of #1: every '
         "particle-particle pair needs the same law"]),
    "group named walls": (_set("particles", "group", "walls"),
                          ['[particles] group must not be "walls"']),
    "negative rolling friction": (_set("contact", "mu_roll", -0.1),
                                  ["[contact] mu_roll must be >= 0"]),
    "negative rolling stiffness": (_set("contact", "k_roll", -1.0),
                                   ["[contact] k_roll must be >= 0"]),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_scene_exits_2_with_one_line(case, tmp_path, capsys):
    edit, fragments = BAD[case]
    scene = base_scene()
    edit(scene, tmp_path)
    path = write_scene(tmp_path, scene)
    code, out, err = run_cli(["run", path, "-o", tmp_path / "out"], capsys)
    assert code == 2
    assert_one_line_error(err, *fragments)
    assert not (tmp_path / "out").exists()
    if case.startswith(("wall ", "pair", "group", "law kinds")):  # materials: --dry-run too
        code, _, err = run_cli(["run", path, "--dry-run"], capsys)
        assert code == 2
        assert_one_line_error(err, *fragments)


def test_unreadable_scene_file(tmp_path, capsys):
    code, _, err = run_cli(["run", tmp_path / "nope.toml"], capsys)
    assert code == 2
    assert_one_line_error(err, "nope.toml: cannot read scene file")


def test_invalid_toml_syntax(tmp_path, capsys):
    path = write_scene(tmp_path, "[simulation]\nsteps = = 3\n")
    code, _, err = run_cli(["run", path], capsys)
    assert code == 2
    assert_one_line_error(err, "scene.toml: invalid TOML", "line 2")


def test_bad_arguments_are_one_line(tmp_path, capsys):
    code, _, err = run_cli(["run"], capsys)
    assert code == 2
    assert_one_line_error(err, "scene")
    code, _, err = run_cli([], capsys)
    assert code == 2
    assert_one_line_error(err, "command is required")


def test_help_exits_0(capsys):
    code, out, _ = run_cli(["--help"], capsys)
    assert code == 0 and "run" in out
    code, out, _ = run_cli(["run", "--help"], capsys)
    assert code == 0 and "--overwrite" in out


# --------------------------------------------------------------------------- valid runs
def test_valid_scene_runs(tmp_path, capsys):
    path = write_scene(tmp_path, base_scene())
    out_dir = tmp_path / "out"
    code, out, err = run_cli(["run", path, "-o", out_dir], capsys)
    assert code == 0, err
    assert "Traceback" not in err
    assert "8 spheres, 1 walls (3D)" in out and "40 x dt" in out
    if _h5_writer_available():
        assert (out_dir / "scene.h5").exists()
        # the XDMF files ParaView and meshio open are named, and exist
        xdmf = [ln for ln in out.splitlines() if ln.startswith("  xdmf ")]
        names = xdmf[0].split(None, 1)[1].split(", ") if len(xdmf) == 1 else []
        assert "scene.xdmf" in names and "scene_walls.xdmf" in names
        assert all((out_dir / n).exists() for n in names)
        # a second run refuses to replace the output, then --overwrite replaces it
        code, _, err = run_cli(["run", path, "-o", out_dir], capsys)
        assert code == 2
        assert_one_line_error(err, "scene.h5 exists", "--overwrite")
        args = ["run", path, "-o", out_dir, "--overwrite", "--steps", "5"]
        code, out, err = run_cli(args, capsys)
        assert code == 0 and "5 x dt" in out, err


def test_a_scene_stops_at_rest(tmp_path, capsys):
    """rest_speed ends the run at the first check where every sphere is slower; the
    state at rest is the last frame; without rest, steps is the cap."""
    from dem.io import read_frame

    scene = base_scene()
    scene["simulation"].update(steps=20000, rest_speed=0.01, damping=0.3)
    path = write_scene(tmp_path, scene)
    code, out, err = run_cli(["run", path, "-o", tmp_path / "out"], capsys)
    assert code == 0, err
    steps = int(out.split("steps")[1].split(" x dt")[0])
    assert 0 < steps < 20000 and steps % 100 == 0
    assert ", at rest (below 0.01 m/s)" in out
    last = read_frame(tmp_path / "out" / "scene.h5", -1)
    assert last["step"] == steps
    speed = np.linalg.norm(last["vel"], axis=1)
    assert speed.max() < 0.01
    # the same scene with a rest speed it cannot reach runs every step
    scene["simulation"].update(steps=300, rest_speed=1e-12)
    path = write_scene(tmp_path, scene, name="restless.toml")
    code, out, err = run_cli(["run", path, "-o", tmp_path / "out2"], capsys)
    assert code == 0, err
    assert "300 x dt" in out and ", not at rest (still above 1e-12 m/s)" in out


def test_largest_speed_counts_spin():
    """A sphere rolling in place is not at rest: its surface moves at |omega| r."""
    import dem
    from dem.rest import largest_speed, run_until_rest

    b = dem.Bodies.empty(3)
    b.add_spheres([[0.0, 0.0, 0.01]], 0.01, density=2500.0)
    b.add_plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], velocity=[5.0, 0.0, 0.0])
    b.ang_vel[0] = [0.0, 3.0, 0.0]
    sim = dem.Simulation(b, dem.LinearSpring(kn=1e4, kt=5e3, mu=0.5))
    assert largest_speed(sim) == pytest.approx(0.03)  # the moving wall does not count
    with pytest.raises(ValueError, match="speed must be > 0"):
        run_until_rest(sim, 10, 0.0)


def test_default_output_dir_and_dry_run(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = write_scene(tmp_path, base_scene(), name="drop.toml")
    code, out, err = run_cli(["run", path, "--dry-run"], capsys)
    assert code == 0, err
    assert "valid" in out and str(Path("output") / "drop" / "drop.h5") in out
    assert not (tmp_path / "output").exists()


def test_simulation_failure_exits_1(tmp_path, capsys):
    scene = base_scene()
    scene["simulation"]["overlap_limit"] = 1e-9  # the resting spheres exceed it at once
    path = write_scene(tmp_path, scene)
    code, _, err = run_cli(["run", path, "-o", tmp_path / "out"], capsys)
    assert code == 1
    assert_one_line_error(err, "simulation failed", "overlap")


def test_subprocess_valid_and_invalid(tmp_path):
    path = write_scene(tmp_path, base_scene())
    code, out, err = run_subprocess(["run", path, "-o", tmp_path / "out"], tmp_path)
    assert code == 0, err
    assert "Traceback" not in err and "40 x dt" in out
    scene = base_scene()
    _overlapping_file(scene, tmp_path)
    bad = write_scene(tmp_path, scene, name="bad.toml")
    code, out, err = run_subprocess(["run", bad], tmp_path)
    assert code == 2
    assert_one_line_error(err, "bad.toml: [particles] file", "particles 1 and 2")


# --------------------------------------------------------------------------- the module
def test_example_scene_is_valid():
    scene = load_scene(EXAMPLE)
    assert scene["particles"]["count"] == 300 and len(scene["walls"]) == 5


def test_load_scene_fills_defaults(tmp_path):
    scene = load_scene(write_scene(tmp_path, base_scene()))
    assert scene["simulation"]["dim"] == 3 and scene["simulation"]["dt"] is None
    assert scene["walls"][0]["velocity"] == [0.0, 0.0, 0.0]
    assert scene["output"] == {"dir": None, "every": 20, "contacts": True,
                               "checkpoint_every": 0}


def test_2d_random_scene_builds(tmp_path):
    from dem.io.scene import build_simulation

    scene = base_scene()
    scene["simulation"] = {"dim": 2, "steps": 1, "gravity": [0.0, -9.81]}
    scene["particles"] = {"generator": "random", "count": 50, "lo": [0.0, 0.0],
                          "hi": [0.1, 0.1], "radius": [0.003, 0.004], "density": 1000.0}
    scene["walls"] = [{"point": [0.0, 0.0], "normal": [0.0, 1.0]}]
    sim, output = build_simulation(load_scene(write_scene(tmp_path, scene)))
    b = sim.bodies
    assert b.dim == 2 and b.n == 51
    i, j = np.triu_indices(50, k=1)
    gap = np.linalg.norm(b.pos[i] - b.pos[j], axis=1) - b.radius[i] - b.radius[j]
    assert gap.min() >= 0.0  # random packing: no overlaps
    r = b.radius[:50, None]
    assert np.all((b.pos[:50] >= r) & (b.pos[:50] <= 0.1 - r))  # inside lo..hi
    assert output.every == 20


def test_file_generator_with_hertz_mindlin(tmp_path):
    from dem import HertzMindlin
    from dem.io.scene import build_simulation

    scene = base_scene()
    _particle_file(scene, tmp_path, ["0.02 0.02 0.01 0.005", "0.04 0.02 0.01 0.004"])
    scene["contact"] = {"law": "hertz_mindlin", "young": 1e7, "poisson": 0.3,
                        "mu": 0.4, "restitution": 0.8}
    sim, _ = build_simulation(load_scene(write_scene(tmp_path, scene)))
    assert sim.bodies.radius[:2].tolist() == [0.005, 0.004]
    assert isinstance(sim.model.laws["pp"][None], HertzMindlin)


def test_particle_file_with_wrong_columns(tmp_path):
    from dem.io.scene import build_simulation

    scene = base_scene()
    _particle_file(scene, tmp_path, ["0.02 0.02 0.005"])
    with pytest.raises(SceneError, match=r"\[particles\] file: .* must have 4 columns"):
        build_simulation(load_scene(write_scene(tmp_path, scene)))


def test_schema_is_documented():
    doc = schema_markdown()
    for name, section in SCHEMA.items():
        for key, spec in section.keys.items():
            assert f"`{key}`" in doc
            assert spec.doc, f"{name}.{key} has no description"
    assert issubclass(SceneError, ValueError)


# --------------------------------------------------------------------------- periodic boxes
def _periodic_scene():
    """Disks falling onto a floor in a box periodic along x (2D)."""
    return {
        "simulation": {"dim": 2, "steps": 3000, "gravity": [0.0, -9.81],
                       "damping": 0.1},
        "domain": {"periodic": ["x"], "lo": [0.0, 0.0], "hi": [0.05, 0.2]},
        "particles": {"generator": "random", "count": 40, "lo": [0.0, 0.0],
                      "hi": [0.05, 0.1], "radius": [0.002, 0.003], "density": 2500.0,
                      "seed": 3, "velocity": [0.0, 0.0]},
        "walls": [{"point": [0.0, 0.0], "normal": [0.0, 1.0]}],
        "contact": {"law": "linear", "kn": 1.0e4, "kt": 5.0e3, "mu": 0.5,
                    "restitution": 0.5},
        "output": {"every": 1000},
    }


def test_a_periodic_box_wraps_and_conserves_momentum_along_it(tmp_path):
    """A gas of disks with random velocities, periodic along x and open along y:
    bodies wrap into the box, pairs meet across its boundary, and the contact forces,
    equal and opposite, keep the total momentum to round-off."""
    from dem.io.scene import build_simulation, load_scene

    scene = _periodic_scene()
    scene["simulation"].update(gravity=[0.0, 0.0], damping=0.0)
    scene["walls"] = []
    sim, _ = build_simulation(load_scene(write_scene(tmp_path, scene)))
    assert sim.box is not None and sim.box.periodic.tolist() == [True, False]
    rng = np.random.default_rng(0)
    sim.bodies.vel[:] = rng.normal(0.0, 0.05, sim.bodies.vel.shape)
    m = sim.bodies.mass[:, None]
    p0 = (m * sim.bodies.vel).sum(axis=0)
    crossed = 0
    for _ in range(10):
        sim.run(300, progress=False)
        crossed += int(np.any(sim.neighbors.img[:, 0] != 0))
    x = sim.bodies.pos[:, 0]
    assert np.all((x >= 0.0) & (x < 0.05))
    assert crossed > 0  # pairs across the periodic boundary
    p1 = (m * sim.bodies.vel).sum(axis=0)
    scale = float((m * np.abs(sim.bodies.vel)).sum())
    assert np.all(np.abs(p1 - p0) < 1e-12 * scale)


@pytest.mark.parametrize("edit, message", [
    (lambda s: s["domain"].pop("lo"), "[domain] missing required key 'lo' of a periodic box"),
    (lambda s: s["domain"].update(periodic=["x", "x"]),
     "[domain] periodic must be a list of distinct axes among"),
    (lambda s: s["domain"].update(periodic=["z"]),
     '[domain] periodic must be a list of distinct axes among ["x", "y"], got ["z"]'),
    (lambda s: s["particles"].update(hi=[0.06, 0.1]),
     "[particles] the generation box lo..hi must lie inside the [domain] along its "
     "periodic axis x"),
    (lambda s: s["walls"].append({"point": [0.0, 0.0], "normal": [1.0, 0.0]}),
     "[[walls]] #2 a wall's normal must have no component along a periodic axis (x)"),
])
def test_a_bad_periodic_box_is_one_line(tmp_path, capsys, edit, message):
    scene = _periodic_scene()
    edit(scene)
    code, _, err = run_cli(["run", write_scene(tmp_path, scene), "--dry-run"], capsys)
    assert code == 2
    assert_one_line_error(err, message)


# --------------------------------------------------------------------------- insertion
def _insert_scene():
    """Disks poured into a 2D box from a region above it, 2000 a second."""
    return {
        "simulation": {"dim": 2, "steps": 4000, "gravity": [0.0, -9.81]},
        "particles": {"generator": "lattice", "count": 4, "lo": [0.0, 0.0],
                      "hi": [0.05, 0.02], "radius": 0.003, "density": 2500.0},
        "insert": {"count": 30, "rate": 2000.0, "lo": [0.0, 0.03], "hi": [0.05, 0.08],
                   "radius": [0.003, 0.004], "velocity": [0.0, -0.2], "every": 50},
        "walls": [{"point": [0.0, 0.0], "normal": [0.0, 1.0]},
                  {"point": [0.0, 0.0], "normal": [1.0, 0.0]},
                  {"point": [0.05, 0.0], "normal": [-1.0, 0.0]}],
        "contact": {"law": "linear", "kn": 1.0e6, "kt": 5.0e5, "mu": 0.5,
                    "restitution": 0.5},
        "output": {"every": 500},
    }


def test_particles_are_inserted_over_time(tmp_path, capsys):
    from dem.io import read_frames
    from dem.io.scene import build_simulation, load_scene

    scene = load_scene(write_scene(tmp_path, _insert_scene()))
    sim, _ = build_simulation(scene)
    inserter = sim.controllers[0]
    sim.run(300, progress=False)
    t = sim.time
    # due by the last insertion (every 50 steps), as room allows
    assert 0 < inserter.inserted <= min(30, int(2000.0 * t))
    sim.run(3700, progress=False)
    assert inserter.inserted == 30 and sim.bodies.n == 4 + 3 + 30
    new = inserter.ids
    r = sim.bodies.radius[new]
    assert np.all((r >= 0.003) & (r <= 0.004))
    # no two particles overlap by more than a sliver, none fell through the floor
    d = np.linalg.norm(sim.bodies.pos[new][:, None] - sim.bodies.pos[new][None], axis=2)
    gap = d - r[:, None] - r[None] + np.eye(len(new))
    assert gap.min() > -0.3 * r.min()
    assert np.all(sim.bodies.pos[new, 1] > 0.0)
    # through dem run: the frames grow as particles arrive
    code, out, err = run_cli(["run", write_scene(tmp_path, _insert_scene()), "-o",
                              tmp_path / "out"], capsys)
    assert code == 0, err
    frames = read_frames(tmp_path / "out" / "scene.h5")
    counts = [len(f["id"]) for f in frames.frames]
    assert counts[0] == 4 and counts[-1] == 34 and counts == sorted(counts)


@pytest.mark.parametrize("edit, message", [
    (lambda s: s["insert"].pop("rate"), "[insert] missing required key 'rate'"),
    (lambda s: s["insert"].update(hi=[0.005, 0.1]),
     "[insert] the region must be wider than a particle's diameter"),
    (lambda s: s["insert"].update(radius=0.001),
     "[insert] inserted particles of radius 0.001 m and density 2500 kg/m^3"),
])
def test_a_bad_insertion_is_one_line(tmp_path, capsys, edit, message):
    scene = _insert_scene()
    edit(scene)
    code, _, err = run_cli(["run", write_scene(tmp_path, scene), "--dry-run"], capsys)
    assert code == 2
    assert_one_line_error(err, message)
