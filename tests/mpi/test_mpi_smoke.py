"""MPI smoke test: ``make test-mpi``, i.e.

    NUMBA_NUM_THREADS=1 mpiexec -n 2 python -m mpi4py -m pytest -q \
        -p no:cacheprovider tests/mpi

Every rank runs the same small DEM scene; the final states are gathered on rank 0 and
must be bit-identical (the engine has no hidden random state and no rank-dependent
arithmetic). Assertion outcomes are broadcast, so all ranks pass or fail together and
none is left waiting in a collective.
"""

import numpy as np
import pytest

MPI = pytest.importorskip("mpi4py.MPI")

import dem  # noqa: E402

pytestmark = pytest.mark.mpi

R, RHO = 0.01, 2500.0


def pour(seed=0):
    """40 disks with friction dropped on a floor between two walls, 400 steps."""
    rng = np.random.default_rng(seed)
    i, j = np.meshgrid(np.arange(8), np.arange(5), indexing="ij")
    pos = 2.2 * R * np.stack([i, j], -1).reshape(-1, 2).astype(float) + [2 * R, 2 * R]
    pos += 0.05 * R * rng.uniform(-1.0, 1.0, pos.shape)
    bodies = dem.Bodies.spheres(
        pos,
        radius=R * rng.uniform(0.9, 1.0, 40),
        density=RHO,
        vel=rng.normal(0.0, 0.2, pos.shape),
    )
    bodies.add_plane([0.0, 0.0], [0.0, 1.0])
    bodies.add_plane([0.0, 0.0], [1.0, 0.0])
    bodies.add_plane([20 * R, 0.0], [-1.0, 0.0])
    law = dem.LinearSpring(kn=1e5, kt=4e4, mu=0.4, restitution=0.5)
    sim = dem.Simulation(bodies, law, gravity=[0.0, -9.81])
    start = bodies.pos.copy()
    sim.run(400)
    return start, sim


def all_ranks(comm, ok):
    """True on every rank iff ``ok`` is true on rank 0 (rank 0 decides, all learn)."""
    return comm.bcast(bool(ok) if comm.rank == 0 else None, root=0)


def test_same_scene_is_bit_identical_on_every_rank():
    comm = MPI.COMM_WORLD
    start, sim = pour()
    state = np.ascontiguousarray(
        np.concatenate([sim.bodies.pos, sim.bodies.vel], axis=1)
    )
    assert not np.array_equal(sim.bodies.pos, start)  # it moved
    assert np.all(np.isfinite(state))
    gathered = np.empty((comm.size, *state.shape)) if comm.rank == 0 else None
    comm.Gather(state, gathered, root=0)
    same = comm.rank != 0 or all(np.array_equal(g, gathered[0]) for g in gathered)
    assert all_ranks(comm, same), "ranks disagree on the final positions/velocities"


def test_launched_on_two_ranks():
    comm = MPI.COMM_WORLD
    if comm.size == 1:
        pytest.skip("a single process: run through `make test-mpi` (mpiexec -n 2)")
    assert comm.size == 2
