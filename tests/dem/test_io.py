"""Output, checkpoint/restart and the demo (dem.io, dem.demo)."""

import os
import xml.etree.ElementTree as ET

import h5py
import numpy as np
import pytest

import dem
from dem._jit import get_threads, set_threads
from dem.io import (H5Writer, load_checkpoint, read_bodies, read_frame, save_checkpoint,
                    write_last_good_state)

LAW = dem.LinearSpring(kn=1.0e4, kt=3.0e3, mu=0.4, restitution=0.5)
R = 0.01  # [m]
GAP = 0.0015  # [m], initial gap between neighbours on the lattice


@pytest.fixture(autouse=True, scope="module")
def one_thread():
    """Small scenes run fastest on one thread (and the machine is shared)."""
    before = get_threads()
    set_threads(1)
    yield
    set_threads(before)


def make_sim(dim, periodic=False, seed=1):
    """~50 polydisperse spheres (disks) just above a floor, with random velocities."""
    rng = np.random.default_rng(seed)
    h = 2 * R + GAP
    shape = (5, 5, 2) if dim == 3 else (10, 5)
    grid = np.stack(np.meshgrid(*[np.arange(k) for k in shape], indexing="ij"), -1)
    pos = grid.reshape(-1, dim) * h + R + GAP
    pos[:, :-1] -= 0.5 * h * (np.array(shape[:-1]) - 1) + R + GAP  # centred
    pos += rng.uniform(-0.2 * GAP, 0.2 * GAP, pos.shape)
    radius = rng.uniform(0.9 * R, R, pos.shape[0])
    density = 2500.0 if dim == 3 else 2500.0 * 2 * R  # 2D: a slab 2R thick [kg/m^2]
    b = dem.Bodies.spheres(pos, radius=radius, density=density)
    b.vel[:] = rng.normal(0.0, 0.1, b.vel.shape)
    up = np.eye(dim)[-1]
    b.add_plane(np.zeros(dim), up)
    box = None
    if periodic:
        half = 0.5 * h * np.array(shape[:-1])
        lo = np.append(-half, 0.0)
        hi = np.append(half, 0.0)
        box = dem.Domain(lo, hi, np.append(np.ones(dim - 1, bool), False))
    return dem.Simulation(b, LAW, gravity=-9.81 * up, damping=0.1, box=box)


def state_of(sim):
    """Every array the run advances, by name (the bodies, neighbour lists, contact state
    bundles, clock, inner list and cell)."""
    out = sim.state_arrays()
    if "inner" in out:  # rows past the inner list's length are scratch
        out["inner"] = out["inner"][:max(int(out["n_inner"][0]), 0)]
    return out


# ------------------------------------------------------------------ restart
@pytest.mark.parametrize("dim, periodic", [(3, False), (2, False), (3, True)],
                         ids=["3d", "2d", "3d-periodic"])
def test_restart_is_bit_for_bit(tmp_path, dim, periodic):
    n_steps = 600
    whole = make_sim(dim, periodic)
    whole.run(n_steps)

    first = make_sim(dim, periodic)
    first.run(n_steps // 2)
    assert np.any(first.pair_state.hist != 0.0), "no tangential history at the checkpoint"
    assert np.any(first.wall_state.whist != 0.0), "no wall contact history at the checkpoint"
    builds_mid = first.neighbors.n_builds
    path = tmp_path / "mid.h5"
    save_checkpoint(first, path)
    assert not os.path.exists(str(path) + ".tmp")

    second = load_checkpoint(path, LAW)
    assert (second.step, second.time, second.dt) == (first.step, first.time, first.dt)
    second.run(n_steps - n_steps // 2)
    assert second.neighbors.n_builds > builds_mid, "no neighbour rebuild after restart"
    assert (second.step, second.time) == (whole.step, whole.time)
    a, b = state_of(whole), state_of(second)
    assert a.keys() == b.keys()
    for k in a:
        assert a[k].dtype == b[k].dtype, k
        assert np.array_equal(a[k], b[k]), f"{k} differs after restart"


def test_restart_from_unprimed_simulation(tmp_path):
    whole = make_sim(3)
    whole.run(100)
    fresh = make_sim(3)
    save_checkpoint(fresh, tmp_path / "start.h5")
    again = load_checkpoint(tmp_path / "start.h5", LAW)
    again.run(100)
    assert np.array_equal(whole.bodies.pos, again.bodies.pos)
    assert np.array_equal(whole.pair_state.hist, again.pair_state.hist)


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory):
    sim = make_sim(3)
    sim.run(50)
    return save_checkpoint(sim, tmp_path_factory.mktemp("ckpt") / "ok.h5")


def _damaged(src, dst, edit):
    with h5py.File(src, "r") as fi, h5py.File(dst, "w") as fo:
        for k, v in fi.attrs.items():
            fo.attrs[k] = v
        for k in fi:
            fi.copy(fi[k], fo, k)
        edit(fo)
    return dst


def _replace(name, value):
    def edit(f):
        del f[name]
        f[name] = value
    return edit


@pytest.mark.parametrize("edit", [
    _replace("bodies/pos", np.zeros((51, 3), np.float32)),
    _replace("bodies/kind", np.zeros(51, np.int64)),
    _replace("contacts/hist", np.zeros((3, 3))),
    lambda f: f["neighbors/pairs"].__setitem__((0, 1), 10_000),
    _replace("gravity", np.zeros(2)),
    lambda f: f.attrs.__setitem__("format", "something else"),
    lambda f: f.attrs.__setitem__("version", 99),
    lambda f: f.__delitem__("contacts"),
], ids=["pos-dtype", "kind-dtype", "hist-shape", "pairs-range", "gravity-shape",
        "format", "version", "missing-group"])
def test_damaged_checkpoint_is_refused(tmp_path, checkpoint, edit):
    bad = _damaged(checkpoint, tmp_path / "bad.h5", edit)
    with pytest.raises(ValueError):
        load_checkpoint(bad, LAW)


def test_foreign_files_are_refused(tmp_path, checkpoint):
    text = tmp_path / "notes.h5"
    text.write_text("not a checkpoint\n")
    with pytest.raises(ValueError, match="not a dem.checkpoint"):
        load_checkpoint(text, LAW)
    cut = tmp_path / "cut.h5"
    cut.write_bytes(open(checkpoint, "rb").read()[:2000])
    with pytest.raises(ValueError):
        load_checkpoint(cut, LAW)
    frames = tmp_path / "frames.h5"
    with H5Writer(frames) as out:
        out(make_sim(2))
    with pytest.raises(ValueError, match="format tag"):
        load_checkpoint(frames, LAW)
    with pytest.raises(FileNotFoundError):
        load_checkpoint(tmp_path / "missing.h5", LAW)


# ------------------------------------------------------------------ HDF5 + XDMF
@pytest.fixture(scope="module", params=[3, 2], ids=["3d", "2d"])
def written(request, tmp_path_factory):
    dim = request.param
    path = tmp_path_factory.mktemp(f"h5_{dim}d") / "run.h5"
    sim = make_sim(dim)
    out = H5Writer(path, every=50)
    out(sim)  # initial frame
    sim.observers.append(out)
    sim.run(200)
    during = (os.path.exists(path), os.path.exists(out.tmp_path))
    out.close()
    return {"sim": sim, "out": out, "path": path, "during": during, "dim": dim}


def test_h5_frames_hold_the_state(written):
    sim, path = written["sim"], written["path"]
    b = sim.bodies
    sph = np.flatnonzero(b.kind == dem.Shape.SPHERE)
    with h5py.File(path, "r") as f:
        assert f.attrs["format"] == "dem.h5writer"
        assert f.attrs["dim"] == written["dim"]
        assert f.attrs["n_frames"] == 5
        steps = [f["frames"][k].attrs["step"] for k in sorted(f["frames"])]
        assert steps == [0, 50, 100, 150, 200]
        for k in f["frames"]:
            g = f["frames"][k]
            assert g.attrs["time"] == g.attrs["step"] * sim.dt
            assert g.attrs["dt"] == sim.dt and g.attrs["dim"] == b.dim
    last = read_frame(path, 4)
    assert np.array_equal(last["id"], sph)
    for k in ("pos", "vel", "rot", "ang_vel", "radius", "force"):
        assert np.array_equal(last[k], getattr(b, k)[sph]), k
    walls = np.flatnonzero(b.kind == dem.Shape.PLANE)
    assert np.array_equal(last["walls"]["normal"], b.normal[walls])
    c = sim.contacts()
    assert last["n_contacts"] == c["i"].size > 0
    for k in ("i", "j", "normal", "overlap", "force", "x1", "x2", "is_wall"):
        assert np.array_equal(last["contacts"][k], c[k]), k
    assert np.all(last["contacts"]["overlap"] > 0.0)


def test_h5_is_published_atomically(written):
    assert written["during"] == (False, True)  # frames go to path.tmp while running
    out = written["out"]
    assert os.path.exists(written["path"]) and not os.path.exists(out.tmp_path)
    assert not os.path.exists(out.xdmf_path + ".tmp")
    assert out.close() == out.path  # idempotent
    with pytest.raises(ValueError, match="closed"):
        out(written["sim"])


def test_xdmf_references_existing_datasets(written):
    out, dim = written["out"], written["dim"]
    root = ET.parse(out.xdmf_path).getroot()
    series = root.find("Domain/Grid")
    assert series.get("CollectionType") == "Temporal"
    grids = series.findall("Grid")
    with h5py.File(written["path"], "r") as f:
        assert len(grids) == f.attrs["n_frames"]
        times = [f["frames"][k].attrs["time"] for k in sorted(f["frames"])]
        assert [float(g.find("Time").get("Value")) for g in grids] == times
        n_refs = 0
        for item in root.iter("DataItem"):
            if item.get("Format") != "HDF":
                continue
            fname, dset = item.text.strip().split(":")
            here = os.path.dirname(out.xdmf_path)
            assert os.path.join(here, fname) == str(written["path"])
            shape = tuple(int(s) for s in item.get("Dimensions").split())
            assert f[dset].shape == shape, dset
            n_refs += 1
    assert n_refs >= 4 * len(grids)
    names = {"position", "id", "kind", "radius", "vel", "force", "ang_vel", "quat"}
    for g in grids:
        assert g.find("Topology").get("TopologyType") == "Polyvertex"
        assert g.find("Geometry").get("GeometryType") == "XYZ"  # 2D: padded points
        attrs = {a.get("Name"): a for a in g.findall("Attribute")}
        assert set(attrs) == (names | {"angle"} if dim == 2 else names)
        for vec in ("vel", "force"):
            assert attrs[vec].get("AttributeType") == "Vector"
            assert attrs[vec].find("DataItem").get("Dimensions").split()[-1] == "3"
    text = open(out.xdmf_path).read()
    assert 'Version="3.0"' in text and "Function" not in text and "HyperSlab" not in text
    assert sorted(out.xdmf_paths) == sorted(
        p for k, p in dem.io.xdmf.xdmf_files(out.xdmf_path).items()
        if k not in ("shapes", "meshes"))  # the scene has neither


@pytest.mark.parametrize("dim", [2, 3])
def test_contact_lines_join_the_centres_across_periodic_sides(tmp_path, dim):
    """A contact across a periodic side is drawn to the neighbour's image: no line is
    longer than the two radii; a wall contact ends at its contact point."""
    sim = make_sim(dim, periodic=True)
    sim.run(400)
    path = tmp_path / "periodic.h5"
    with H5Writer(path) as out:
        out(sim)
    c = read_frame(path, 0)["contacts"]
    b = sim.bodies
    ends = c["xdmf"]["points"].reshape(-1, 2, 3)
    assert np.array_equal(ends[:, 0, :dim], b.pos[c["i"]])
    length = np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1)
    pair = ~c["is_wall"]
    reach = b.radius[c["i"]] + np.where(pair, b.radius[c["j"]], 0.0)
    assert np.all(length <= reach) and np.any(pair)
    far = np.linalg.norm(b.pos[c["j"]] - b.pos[c["i"]], axis=1) > reach
    assert np.any(far & pair) or dim == 3  # 2D: some contacts cross a periodic side
    wall_point = 0.5 * (c["x1"] + c["x2"])[~pair]
    np.testing.assert_allclose(ends[~pair, 1, :dim], wall_point, rtol=0, atol=1e-15)
    fn = np.einsum("kd,kd->k", c["force"], c["normal"])
    assert np.array_equal(c["normal_force"], fn)
    np.testing.assert_allclose(c["tangential_force"] + fn[:, None] * c["normal"],
                               c["force"], rtol=0, atol=1e-15 * np.abs(fn).max())


def test_stale_xdmf_companions_are_removed(tmp_path):
    """Rewriting an output without contacts removes the contacts file of the last."""
    path = tmp_path / "run.h5"
    for contacts in (True, False):
        sim = make_sim(3)
        sim.run(300)
        with H5Writer(path, contacts=contacts) as out:
            out(sim)
    files = dem.io.xdmf.xdmf_files(out.xdmf_path)
    assert out.xdmf_paths == [files["particles"], files["walls"]]
    assert not os.path.exists(files["contacts"])


def test_writer_context_manager_publishes_on_error(tmp_path):
    path = tmp_path / "err.h5"
    with pytest.raises(RuntimeError):
        with H5Writer(path) as out:
            out(make_sim(3))
            raise RuntimeError("boom")
    assert read_frame(path, 0)["step"] == 0
    assert not os.path.exists(str(path) + ".tmp")


# ------------------------------------------------------------------ failure output
def _head_on(skin):
    """Two spheres closing at 40 m/s: the overlap limit trips on the second step."""
    b = dem.Bodies.spheres([[0.0, 0.0, 0.0], [2 * R + 1e-3, 0.0, 0.0]], radius=R,
                           density=2500.0, vel=[[20.0, 0.0, 0.0], [-20.0, 0.0, 0.0]])
    return dem.Simulation(b, LAW, dt=1e-4, skin=skin, allow_unstable_dt=True)


def test_last_good_state_is_written_on_failure(tmp_path):
    sim = _head_on(skin=0.05)  # no neighbour rebuild before the failure
    start = sim.bodies.copy()
    path = tmp_path / "fail" / "last_good.h5"
    sim.on_failure(write_last_good_state(path))
    with pytest.raises(dem.SimulationError):
        sim.run(10)
    good = read_bodies(path)
    assert good.n == 2 and good.dim == 3
    for k in dem.Bodies.ARRAYS:  # the state before the failing chunk of steps
        assert np.array_equal(getattr(good, k), getattr(start, k)), k
    with h5py.File(path, "r") as f:
        assert f.attrs["failed_at_step"] == sim.step and f.attrs["is_last_good"]


def test_last_good_state_after_a_rebuild_is_not_mid_step(tmp_path):
    sim = _head_on(skin=None)  # default skin: the list is rebuilt mid-step first
    path = tmp_path / "last_good.h5"
    sim.on_failure(write_last_good_state(path))
    with pytest.raises(dem.SimulationError):
        sim.run(10)
    good = read_bodies(path)
    gap = np.linalg.norm(good.pos[1] - good.pos[0]) - 2 * R
    assert gap > -sim.overlap_limit * R


# ------------------------------------------------------------------ demo
def test_demo_pours_to_rest(tmp_path):
    from dem import demo

    res = demo.run_demo(str(tmp_path), n_spheres=150, seed=3)
    assert res["at_rest"]
    assert res["kinetic"][-1] < demo.REST * res["released"]
    b = res["sim"].bodies
    sph = b.kind == dem.Shape.SPHERE
    half = 0.5 * demo.BOX
    assert np.all(b.pos[sph, 2] > 0.0)
    assert np.all(np.abs(b.pos[sph, :2]) < half)
    assert os.path.exists(res["h5"]) and os.path.exists(res["xdmf"])
    fig = demo.visualize(res)
    fig.savefig(tmp_path / "pour.png")
    assert (tmp_path / "pour.png").stat().st_size > 0
