"""The contact-state bundles (dem.state): one list of what a step carries to the next,
which snapshots, restores and checkpoints all iterate."""

import h5py
import numpy as np
import pytest

import dem
from dem.io import load_checkpoint, save_checkpoint
from dem.state import PairState, ShapePairState, ShapeWallState, WallState

from test_io import LAW, make_sim, one_thread, state_of  # noqa: F401 (fixture)

COUNTS = {"pair": 5, "wall": 2, "body": 4}


@pytest.mark.parametrize("cls", [PairState, WallState, ShapePairState, ShapeWallState])
@pytest.mark.parametrize("dim", [2, 3])
def test_bundle_columns_give_the_shapes(cls, dim):
    z = cls.zeros(COUNTS, dim)
    r = 1 if dim == 2 else 3
    expect = {"hist": (5, 3), "touch": (5,), "fpair": (5, dim), "whist": (2, 3),
              "wforce": (2, dim), "wtorque": (2, r), "warm": (5, 16), "iters": (5,),
              "pgeom": (5, 7), "tpair": (5, 2 * r), "wwarm": (2, 16), "witers": (2,),
              "wgeom": (2, 7)}
    assert {k: v.shape for k, v in z._asdict().items()} == {k: expect[k] for k in z._fields}
    assert all(np.all(a == 0) for a in z)
    assert cls.checked(z._asdict(), COUNTS, dim) == z  # the same arrays


def test_checked_names_the_wrong_field():
    good = PairState.zeros(COUNTS, 3)._asdict()
    with pytest.raises(ValueError, match=r"^x: fpair is float64\[5, 2\], expected "
                                         r"float64\[5, 3\]$"):
        PairState.checked(good | {"fpair": np.zeros((5, 2))}, COUNTS, 3, "x: ")
    with pytest.raises(ValueError, match="touch is int64"):
        PairState.checked(good | {"touch": np.zeros(5, np.int64)}, COUNTS, 3)
    with pytest.raises(ValueError, match="^hist is missing$"):
        PairState.checked({k: v for k, v in good.items() if k != "hist"}, COUNTS, 3)


def test_a_bundle_needs_one_column_per_field():
    from typing import NamedTuple

    class Bad(NamedTuple):
        a: np.ndarray
        b: np.ndarray
        COLUMNS = (dem.state.Column("pair", (), np.float64, "a"),)

    with pytest.raises(TypeError, match="one column per field"):
        dem.state.bundle(Bad)


def test_checkpoint_contacts_are_the_bundles_fields(tmp_path):
    sim = make_sim(3)
    sim.run(50)
    fields = {k for b in sim.state_bundles().values() for k in b._fields}
    assert fields == {"hist", "touch", "fpair", "whist", "wforce", "wtorque"}
    save_checkpoint(sim, tmp_path / "c.h5")
    with h5py.File(tmp_path / "c.h5") as f:
        written = set(f["contacts"])
    assert written == fields | {"radius_ref", "inner", "pos_inner"}
    assert fields <= set(sim.snapshot())


def test_restore_across_a_rebuild_reallocates_and_repeats(tmp_path):
    """A snapshot taken before the neighbour list changed size restores into the new
    arrays' place and the run repeats bit for bit."""
    sim = make_sim(2)
    sim.run(20)
    snap = sim.snapshot()
    sim.run(400)
    assert sim.neighbors.pairs.shape != snap["nl.pairs"].shape  # rebuilt, resized
    after = {k: v.copy() for k, v in state_of(sim).items()}
    sim.restore(snap)
    assert sim.pair_state.hist.shape == snap["hist"].shape
    sim.run(400)
    again = state_of(sim)
    for k in after:
        assert np.array_equal(after[k], again[k]), k


def test_checkpoint_without_touch_flags_still_restarts(tmp_path):
    """Files written before the touch flags were kept: a pair with history touches."""
    first = make_sim(3)
    first.run(100)
    save_checkpoint(first, tmp_path / "c.h5")
    with h5py.File(tmp_path / "c.h5", "r+") as f:
        del f["contacts/touch"]
    second = load_checkpoint(tmp_path / "c.h5", LAW)
    assert np.array_equal(second.pair_state.touch,
                          np.any(first.pair_state.hist != 0.0, axis=1))
    assert second.pair_state.touch.any()
    second.run(100)
    assert second.step == 200
