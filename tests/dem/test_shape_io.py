"""Bodies with level-set shapes written and read back (packings are made once, reused).

The shape table travels with the bodies, checked on reading: a file whose offsets,
indices or geometry are inconsistent is refused with a message naming the dataset,
before anything is built from it. User-defined shapes are code, not data: writing them
is refused.
"""

import h5py
import numba
import numpy as np
import pytest

import dem
from dem.io.checkpoint import read_bodies, write_bodies


def _scene():
    rng = np.random.default_rng(5)
    b = dem.Bodies.empty(3)
    b.add_shapes(dem.Box([0.02, 0.01, 0.015]), rng.uniform(0, 1, (3, 3)), 2500.0)
    b.add_shapes(dem.ConvexPolyhedron.from_vertices(rng.normal(size=(10, 3)) * 0.01),
                 rng.uniform(0, 1, (2, 3)), 2500.0)
    b.add_spheres(rng.uniform(0, 1, (2, 3)), 0.01, 2500.0)
    b.add_plane([0, 0, 0], [0, 0, 1])
    return b


def test_shapes_round_trip(tmp_path):
    b = _scene()
    write_bodies(b, tmp_path / "p.h5")
    r = read_bodies(tmp_path / "p.h5")
    for name in dem.Bodies.ARRAYS:
        assert np.array_equal(getattr(r, name), getattr(b, name)), name
    for name in ("kind", "param", "scale", "brad", "vstart", "verts", "fstart", "faces",
                 "tstart", "tris", "xform"):
        assert np.array_equal(getattr(r.table, name), getattr(b.table, name)), name


@pytest.mark.parametrize("name, value, message", [
    ("tris", 99, "tris of row"),
    ("vstart", -1, "not a valid offset array"),
    ("scale", -1.0, "non-finite or non-positive"),
    ("kind", 5, "non-storable shape kind"),
])
def test_corrupt_table_is_refused(tmp_path, name, value, message):
    write_bodies(_scene(), tmp_path / "p.h5")
    with h5py.File(tmp_path / "p.h5", "r+") as f:
        d = f["bodies/shape_table"][name]
        data = d[()]
        data.flat[1] = value
        d[...] = data
    with pytest.raises(ValueError, match=message):
        read_bodies(tmp_path / "p.h5")


def test_custom_shapes_are_not_written(tmp_path):
    @numba.njit
    def ball(x, y, z, p):
        return np.sqrt(x * x + y * y) - p[0]

    b = dem.Bodies.empty(2)
    b.add_shapes(dem.CustomShape(ball, 0.011, 2, params=(0.01,)), [[0.0, 0.0]], 1000.0)
    with pytest.raises(ValueError, match="user-defined shape"):
        write_bodies(b, tmp_path / "c.h5")
    assert not (tmp_path / "c.h5").exists()


@pytest.mark.parametrize("detection", ["auto", "admm"])
def test_checkpoint_restart_is_bit_for_bit(tmp_path, detection):
    """A 2D pile of polygons: save at step 150, run on; the restart repeats it exactly
    (ADMM's warm starts are part of the saved state)."""
    from dem.io.checkpoint import load_checkpoint, save_checkpoint

    law = dem.LinearSpring(kn=1e5, kt=5e4, mu=0.4, restitution=0.5)

    def pile():
        rng = np.random.default_rng(3)
        b = dem.Bodies.empty(2)
        shape = dem.ConvexPolygon.regular(5, 0.01)
        k = np.arange(24)
        pos = np.stack([0.021 * (k % 6), 0.012 + 0.021 * (k // 6)], axis=1)
        b.add_shapes(shape, pos, 2500.0, rot=rng.uniform(0, np.pi, 24),
                     vel=rng.normal(0, 0.1, (24, 2)))
        b.add_plane([0, 0], [0, 1])
        return dem.Simulation(b, law, gravity=[0, -9.81], detection=detection, threads=1)

    sim = pile()
    sim.run(150)
    save_checkpoint(sim, tmp_path / "c.h5")
    sim.run(300)
    again = load_checkpoint(tmp_path / "c.h5", law)
    assert again.detection == detection
    again.run(300)
    assert len(sim.contacts()["i"]) > 5
    for name in ("pos", "vel", "rot", "ang_vel"):
        assert np.array_equal(getattr(sim.bodies, name), getattr(again.bodies, name)), name
