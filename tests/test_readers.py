"""Self-describing files and their readers: every file the project writes carries its
format, version, the project version and the configuration that made it; every
dataset its unit (and sign); ``dem.io.read_frames`` and ``hmm.read_fields`` give back
exactly what was written, and refuse other files in one line; a restart refuses to
write into a file it did not make."""

import contextlib
import io
import json
import os

import h5py
import numpy as np
import pytest
from problems import elastic_problem

import dem
import hmm
from dem.io import read_frames, save_checkpoint, write_bodies
from dem.io.meta import software
from skfem import MeshQuad

SCENE = """
[simulation]
steps = 40
gravity = [0.0, 0.0, -9.81]

[particles]
generator = "lattice"
count = 8
lo = [0.0, 0.0, 0.0]
hi = [0.03, 0.03, 0.03]
radius = 0.005
density = 2500.0

[[walls]]
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]

[contact]
law = "linear"
kn = 1.0e4
kt = 5.0e3
mu = 0.5
restitution = 0.5

[output]
every = 20
"""

PROBLEM = elastic_problem(3, checkpoint_every=1)


def _main(module, args, cwd):
    """``dem``/``hmm`` ARGS in this process from ``cwd``: (status, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    here = os.getcwd()
    os.chdir(cwd)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                module.main(list(args))
            except SystemExit as exc:
                code = exc.code
    finally:
        os.chdir(here)
    return code, out.getvalue(), err.getvalue()


def _datasets(path):
    """``{path in file: dataset attrs}`` of every dataset of an HDF5 file."""
    out = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda name, obj: out.__setitem__(name, dict(obj.attrs))
                     if isinstance(obj, h5py.Dataset) else None)
    return out


def _assert_every_dataset_has_a_unit(path):
    found = _datasets(path)
    assert found
    bad = {k: a.get("unit") for k, a in found.items()
           if a.get("unit") in (None, "unknown", "-")}
    assert not bad, f"{path}: datasets without a unit: {bad}"


def _assert_tagged(path, fmt, version, config=True):
    with h5py.File(path, "r") as f:
        assert f.attrs["format"] == fmt
        assert f.attrs["version"] == version
        assert f.attrs["software"] == software()
        if config:
            assert f.attrs["config"]


# --------------------------------------------------------------------------- dem
@pytest.fixture(scope="module")
def dem_run(tmp_path_factory):
    from dem import cli

    tmp = tmp_path_factory.mktemp("dem")
    (tmp / "scene.toml").write_text(SCENE)
    code, _, err = _main(cli, ["run", "scene.toml", "-o", "out", "--no-progress"], tmp)
    assert code == 0, err
    (h5,) = (tmp / "out").glob("*.h5")
    return h5


def test_a_particle_file_is_tagged_and_every_dataset_has_its_unit(dem_run):
    _assert_tagged(dem_run, "dem.h5writer", 4)
    with h5py.File(dem_run, "r") as f:
        assert f.attrs["config"] == SCENE  # the scene file that made it
        g = f["frames/000000"]
        assert g["pos"].attrs["unit"] == "m"
        assert g["contacts/normal_force"].attrs["sign"].startswith("compression positive")
        assert g["rot"].attrs["unit"] == "1"  # 3D: a quaternion
    _assert_every_dataset_has_a_unit(dem_run)


def test_read_frames_gives_back_what_was_written(dem_run):
    frames = read_frames(dem_run)
    with h5py.File(dem_run, "r") as f:
        n = f.attrs["n_frames"]
        assert len(frames) == n == 3  # the initial state, steps 20 and 40
        for k in range(n):
            g = f["frames"][f"{k:06d}"]
            assert frames.step[k] == g.attrs["step"]
            assert frames.time[k] == g.attrs["time"]
            for name in ("pos", "vel", "rot", "radius", "walls/normal",
                         "contacts/force", "contacts/normal_force"):
                assert np.array_equal(frames.frames[k][name], g[name][()])
    assert frames["pos"].shape == (3, 8, 3)
    assert np.array_equal(frames["pos"][2], frames.frames[2]["pos"])
    assert frames.units["vel"] == "m/s" and frames.units["contacts/overlap"] == "m"
    assert frames.signs["contacts/overlap"] == "positive in contact"
    assert frames.attrs["config"] == SCENE
    assert not any("xdmf" in name for name in frames.names)
    last = read_frames(dem_run, frames=[-1])
    assert len(last) == 1 and last.step[0] == 40


def test_checkpoints_and_body_dumps_carry_units(tmp_path):
    b = dem.Bodies.spheres([[0.0, 0.0], [0.019, 0.0]], radius=0.01, density=2500.0)
    sim = dem.Simulation(b, dem.LinearSpring(kn=1e4), dt=1e-5)
    sim.run(2)
    path = save_checkpoint(sim, tmp_path / "ck.h5", config={"made_by": "a test"})
    _assert_tagged(path, "dem.checkpoint", 1)
    with h5py.File(path, "r") as f:
        assert json.loads(f.attrs["config"]) == {"made_by": "a test"}
        assert f["bodies/rot"].attrs["unit"] == "rad"  # 2D: an angle
        assert f["bodies/ang_vel"].attrs["unit"] == "rad/s"
        assert f["contacts/fpair"].attrs["unit"] == "N"
    _assert_every_dataset_has_a_unit(path)
    dump = write_bodies(b, tmp_path / "bodies.h5")
    _assert_tagged(dump, "dem.bodies", 1, config=False)
    _assert_every_dataset_has_a_unit(dump)


# --------------------------------------------------------------------------- hmm
@pytest.fixture(scope="module")
def hmm_run(tmp_path_factory):
    from hmm import cli

    tmp = tmp_path_factory.mktemp("hmm")
    (tmp / "p.toml").write_text(PROBLEM)
    code, _, err = _main(cli, ["run", "p.toml", "-o", "out", "--no-progress"], tmp)
    assert code == 0, err
    return tmp


def test_fields_h5_is_tagged_and_every_dataset_has_its_unit(hmm_run):
    out = hmm_run / "out"
    _assert_tagged(out / "fields.h5", "hmm.fields", 2)
    _assert_tagged(out / "checkpoint.h5", "hmm.checkpoint", 1)
    for name in ("fields.h5", "checkpoint.h5"):
        _assert_every_dataset_has_a_unit(out / name)
    with h5py.File(out / "fields.h5", "r") as f:
        assert json.loads(f.attrs["config"])["micro"]["model"] == "linear_elastic"
        g = f["steps/00003"]
        assert "mean_stress" not in g
        assert g["pressure"].attrs["sign"] == "compression positive"
        assert g["stress_yy"].attrs["sign"] == "tension positive"
        assert f["curve/force/top"].attrs["unit"] == "N/m"  # 2D: per metre of thickness
    from PIL import Image

    png = Image.open(out / "load_displacement.png")
    assert png.text["format"] == "femxdem.figure" and png.text["version"] == "1"
    assert png.text["Software"] == software()
    assert png.text["data"] == "fields.h5:/curve"


def test_read_fields_gives_back_what_was_written(hmm_run):
    path = hmm_run / "out" / "fields.h5"
    r = hmm.read_fields(path)
    assert isinstance(r, hmm.Fields) and r.dim == 2 and len(r) == 4
    with h5py.File(path, "r") as f:
        assert np.array_equal(r.points, f["mesh/points"][:, :2].T)
        assert np.array_equal(r.cells, f["mesh/cells"][()].T)
        for k, name in enumerate(sorted(f["steps"])):
            g = f["steps"][name]
            assert r.step[k] == g.attrs["step"] == k
            for key in ("displacement", "stress_yy", "pressure", "gauss/stress"):
                assert np.array_equal(r[key][k], g[key][()])
        for key in ("load_factor", "force/top", "displacement/top"):
            assert np.array_equal(r.curve[key], f["curve"][key][()])
    assert r.units["stress_xx"] == "Pa" and r.signs["stress_xx"] == "tension positive"
    assert r.units["curve/force/top"] == "N/m" and r.units["displacement"] == "m"
    assert r.units["gauss/weights"] == "m^2" and r.units["mesh/points"] == "m"
    # one convention: the pressure is minus the mean normal stress; compressed here
    sig = r["gauss/stress"]
    assert np.all(r["stress_yy"][1:] < 0.0) and np.all(r["pressure"][1:] > 0.0)
    p = -0.5 * (sig[..., 0, 0] + sig[..., 1, 1])  # per Gauss point
    ne = r.cells.shape[1]
    np.testing.assert_allclose(r["pressure"], p.reshape(len(r), ne, -1).mean(axis=2),
                               rtol=1e-12)
    assert r.config["micro"]["young"] == 1e6
    mesh = r.mesh()  # scikit-fem's mesh, on which the displacement lives
    assert isinstance(mesh, MeshQuad) and np.array_equal(mesh.p, r.points)
    assert r["displacement"].shape == (len(r), mesh.p.shape[1], 3)


def test_readers_refuse_each_others_files_and_foreign_ones(hmm_run, dem_run, tmp_path):
    fields = hmm_run / "out" / "fields.h5"
    with pytest.raises(ValueError, match=r"is a 'dem.h5writer' file, not a "
                                         r"'hmm.fields' file"):
        hmm.read_fields(dem_run)
    with pytest.raises(ValueError, match=r"is a 'hmm.fields' file, not a "
                                         r"'dem.h5writer' file"):
        read_frames(fields)
    with h5py.File(tmp_path / "other.h5", "w") as f:
        f.create_dataset("x", data=np.zeros(3))
    for reader in (hmm.read_fields, read_frames):
        with pytest.raises(ValueError, match="an HDF5 file without a format tag"):
            reader(tmp_path / "other.h5")
    (tmp_path / "text.h5").write_text("not HDF5\n")
    for reader in (hmm.read_fields, read_frames):
        with pytest.raises(ValueError, match="is not a readable HDF5 file"):
            reader(tmp_path / "text.h5")
    with h5py.File(tmp_path / "future.h5", "w") as f:
        f.attrs.update(format="hmm.fields", version=99)
    with pytest.raises(ValueError, match="version 99 is not one this reader knows"):
        hmm.read_fields(tmp_path / "future.h5")


def _stopped_run(tmp_path, name):
    from hmm import cli

    (tmp_path / "p.toml").write_text(PROBLEM)
    code, _, err = _main(cli, ["run", "p.toml", "-o", name, "--stop-after", "1",
                               "--no-progress"], tmp_path)
    assert code == 0, err
    return tmp_path / name


@pytest.mark.parametrize("tag", [None, "hmm.batch"])
def test_a_restart_refuses_a_foreign_fields_file_and_leaves_it(tmp_path, tag):
    from hmm import cli

    out = _stopped_run(tmp_path, "cut")
    (out / "fields.h5").unlink()
    with h5py.File(out / "fields.h5", "w") as f:  # another program's file
        f.create_dataset("steps/00000/x", data=np.zeros(3))
        if tag is not None:
            f.attrs["format"] = tag
    before = (out / "fields.h5").read_bytes()
    for extra in ([], ["--dry-run"]):
        code, _, err = _main(cli, ["run", "p.toml", "-o", "cut", "--restart", *extra],
                             tmp_path)
        what = f"a '{tag}' file" if tag else "an HDF5 file without a format tag"
        assert code == 2 and err == (
            f"hmm run: error: cut/fields.h5 is {what}, not a 'hmm.fields' file; "
            f"a restart continues only its own run's file: remove it, or run without "
            f"--restart and with --overwrite to replace it\n")
        assert (out / "fields.h5").read_bytes() == before
    code, _, err = _main(cli, ["run", "p.toml", "-o", "cut", "--overwrite",
                               "--no-progress"], tmp_path)
    assert code == 0, err
    _assert_tagged(out / "fields.h5", "hmm.fields", 2)


def test_a_restart_brings_a_version_1_file_up_to_date(tmp_path):
    """A fields.h5 of version 1 (``mean_stress``, no units) is read as it is and,
    on restart, continued as version 2: renamed, labelled, bit for bit the numbers."""
    from hmm import cli

    out = _stopped_run(tmp_path, "cut")
    path = out / "fields.h5"
    with h5py.File(path, "a") as f:  # as the first version wrote it
        f.attrs["version"] = 1
        for a in ("software", "config"):
            del f.attrs[a]
        for name in f["steps"]:
            f["steps"][name].move("pressure", "mean_stress")

        def strip(_, obj):
            if isinstance(obj, h5py.Dataset):
                for a in ("unit", "sign"):
                    if a in obj.attrs:
                        del obj.attrs[a]

        f.visititems(strip)
        old_p = f["steps/00001/mean_stress"][()]
    r = hmm.read_fields(path)
    assert np.array_equal(r["pressure"][1], old_p) and "mean_stress" not in r.fields
    assert r.units["pressure"] == "Pa" and r.signs["pressure"] == "compression positive"
    code, _, err = _main(cli, ["run", "p.toml", "-o", "cut", "--restart",
                               "--no-progress"], tmp_path)
    assert code == 0, err
    _assert_tagged(path, "hmm.fields", 2)
    _assert_every_dataset_has_a_unit(path)
    r = hmm.read_fields(path)
    assert list(r.step) == [0, 1, 2, 3]
    assert np.array_equal(r["pressure"][1], old_p)
    assert "mean_stress" not in (out / "fields.xdmf").read_text()


# --------------------------------------------------------------------------- rve, batch
def test_rve_test_and_batch_files_carry_units_and_signs(tmp_path):
    from hmm.batch import Store, expand
    from hmm.experiment import CompressionResult
    from hmm.experiment_output import write_h5

    curves = {"axial_strain": np.linspace(0.0, 0.01, 3), "p": np.full(3, 1e5),
              "stress": np.zeros((3, 2, 2)), "void_ratio": np.full(3, 0.2)}
    result = CompressionResult(curves, {"dim": 2}, {"test": {"kind": "drained"}}, True)
    write_h5(tmp_path / "rve_test.h5", result)
    _assert_tagged(tmp_path / "rve_test.h5", "hmm.rve_test", 1)
    _assert_every_dataset_has_a_unit(tmp_path / "rve_test.h5")
    attrs = _datasets(tmp_path / "rve_test.h5")
    assert attrs["axial_strain"]["sign"] == "compression positive (shortening)"
    assert attrs["stress"]["sign"] == "tension positive"
    assert attrs["void_ratio"]["unit"] == "1"
    data = {"base": {"packing": {"count": 40, "radius": 1e-3, "p0": 1e5},
                     "contact": {"law": "linear", "kn": 1e8, "kt": 5e7, "mu": 0.5}},
            "sweep": {"grid": {"test.confining": [5e4, 1e5]}}}
    sweep = expand(data, "s.toml")
    store = Store(tmp_path / "batch.h5", sweep, overwrite=False)
    try:
        store.done(sweep.experiments[0], curves, {"peak_friction_angle": 30.0}, 0)
    finally:
        store.close()
    _assert_tagged(tmp_path / "batch.h5", "hmm.batch", 1)
    _assert_every_dataset_has_a_unit(tmp_path / "batch.h5")
    with h5py.File(tmp_path / "batch.h5", "r") as f:
        assert json.loads(f.attrs["config"]) == data
