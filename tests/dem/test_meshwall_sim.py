"""Triangle-mesh walls in the time step: a mesh plane is a Plane, history survives a
seam, a valley holds a sphere with the analytic forces, moving walls do the work the
energy balance says, a servo through a controller, thread count and restarts change
no bit."""

import os
import subprocess
import sys

import numpy as np
import pytest

import dem
from dem.io import load_checkpoint, save_checkpoint
from dem.meshwall import CUBE_FACES, CUBE_VERTICES

R, RHO = 0.01, 2500.0
MASS = RHO * 4.0 / 3.0 * np.pi * R**3
#: the square [-1, 1]^2 at z = 0 as two triangles sharing the diagonal y = x:
#: face 0 below it (y < x), face 1 above
SQUARE_V = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])
SQUARE_F = np.array([[0, 1, 2], [0, 2, 3]])


def _law(kind):
    if kind == "linear":
        return dem.LinearSpring(kn=1e5, kt=2e4, mu=0.3, restitution=0.7)
    return dem.HertzMindlin(young=1e8, poisson=0.3, restitution=0.7, mu=0.3)


def _pair_runs(law, pos, vel, spin, n_steps, dt, gravity=(0.0, 0.0, -9.81), wall_vel=None):
    """The same sphere against a two-triangle mesh and against a Plane, step by step:
    (mesh rows, plane rows, mesh sim, plane sim), rows of (pos, vel, ang_vel, force,
    torque) of the sphere."""
    out = []
    for mesh in (True, False):
        b = dem.Bodies.spheres([pos], radius=R, density=RHO, vel=[vel])
        b.ang_vel[0] = spin
        walls = []
        if mesh:
            walls = [dem.MeshWall(SQUARE_V, SQUARE_F, velocity=wall_vel)]
        else:
            b.add_plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], velocity=wall_vel)
        sim = dem.Simulation(b, law, dt=dt, gravity=gravity, threads=1, walls=walls)
        rows = []
        for _ in range(n_steps):
            sim.run(1)
            rows.append(np.concatenate([b.pos[0], b.vel[0], b.ang_vel[0], b.force[0],
                                        b.torque[0]]))
        out += [np.array(rows), sim]
    return out[0], out[2], out[1], out[3]


@pytest.mark.parametrize("kind", ["linear", "hertz"])
def test_sphere_on_a_mesh_plane_is_a_sphere_on_a_plane(kind):
    """An oblique, spinning impact with friction: positions, velocities, forces and
    torques of the mesh run equal the Plane run's to round-off."""
    mesh, plane, sim, _ = _pair_runs(_law(kind), [0.3, -0.05, 0.0102], [0.3, 0.1, -0.4],
                                     [5.0, -3.0, 2.0], 1500, 2e-6)
    contact = np.abs(plane[:, 9:11]).max(axis=1) > 0.0  # a tangential force acts
    assert contact.sum() > 50 and not np.isclose(plane[-1, 5], -0.4)
    scale = np.abs(plane).max(axis=0)
    np.testing.assert_allclose(mesh, plane, rtol=0.0, atol=1e-10 * scale.max())
    assert sim.mesh_state.mtouch.sum() == 0  # it bounced off


def test_history_survives_the_seam_between_two_triangles():
    """A sphere sliding and rolling across the shared edge of two coplanar triangles:
    the contact passes from face 1 to face 0 and its force follows the Plane run's
    step by step, with no jump (the tangential spring is handed over)."""
    z0 = R - MASS * 9.81 / 1e5
    mesh, plane, sim, _ = _pair_runs(_law("linear"), [-0.004, 0.0, z0], [0.5, 0.0, 0.0],
                                     [0.0, 0.0, 0.0], 1600, 1e-5)
    assert plane[0, 0] < 0.0 < plane[-1, 0]  # it crossed the diagonal at x = y = 0
    st = sim.mesh_state
    assert st.mrows[st.mtouch == 1, 1].tolist() == [0]  # face 0 reports it now
    ft = np.linalg.norm(plane[:, 9:11], axis=1)
    assert ft.min() > 0.05 * MASS * 9.81  # friction acts all along
    weight = MASS * 9.81
    np.testing.assert_allclose(mesh[:, 9:15], plane[:, 9:15], rtol=0.0, atol=1e-9 * weight)


def test_contact_summary_and_energy_count_a_mesh_contact_as_a_plane_s():
    """The sphere sliding with friction of the seam run, on the mesh and on a Plane
    (800 steps): ``contact_summary`` gives the one contact with the same overlap,
    normal, points, force on the wall, stiffnesses, arms and moment to round-off (its
    ``j`` is -1: the first mesh wall), and ``elastic_energy`` the same energy, the
    tangential spring's included."""
    from dem.observers import contact_summary, elastic_energy

    z0 = R - MASS * 9.81 / 1e5
    _, _, sim, psim = _pair_runs(_law("linear"), [-0.004, 0.0, z0], [0.5, 0.0, 0.0],
                                 [0.0, 0.0, 0.0], 800, 1e-5)
    cm, cp = contact_summary(sim), contact_summary(psim)
    assert cm["j"].tolist() == [-1] and cm["is_wall"].tolist() == [True]
    for k in ("i", "overlap", "normal", "x1", "x2", "branch", "force", "arm_i", "arm_j",
              "kn", "kt", "moment"):
        scale = max(np.abs(cp[k]).max(), 1e-300)
        np.testing.assert_allclose(cm[k], cp[k], rtol=0.0, atol=1e-9 * scale, err_msg=k)
    assert np.abs(cp["force"][0, :2]).max() > 0.05 * MASS * 9.81  # friction acts
    normal_only = 0.5 * 1e5 * cp["overlap"][0] ** 2
    assert elastic_energy(psim) > 1.001 * normal_only  # the tangential spring counts
    assert elastic_energy(sim) == pytest.approx(elastic_energy(psim), rel=1e-9)


def test_sphere_in_a_valley_rests_on_two_analytic_normal_forces():
    """A V-shaped valley (two faces each side, 30 degrees up): a frictionless sphere
    settles on two contacts, each pushing mg / (2 cos 30) along its face's normal."""
    t = np.tan(np.radians(30.0))
    v = np.array([[0, -1, 0], [0, 1, 0], [-1, 1, t], [-1, -1, t], [1, 1, t], [1, -1, t]],
                 dtype=float)
    f = np.array([[0, 1, 2], [0, 2, 3], [0, 4, 1], [0, 5, 4]])
    b = dem.Bodies.spheres([[0.0, 0.0, R / np.cos(np.radians(30.0))]], radius=R,
                           density=RHO)
    law = dem.LinearSpring(kn=1e5, restitution=0.3)
    sim = dem.Simulation(b, law, dt=1e-5, gravity=[0, 0, -9.81], damping=0.3, threads=1,
                         walls=[dem.MeshWall(v, f)])
    sim.run(6000)
    st = sim.mesh_state
    on = st.mtouch == 1
    assert on.sum() == 2 and sorted(np.sign(st.mpoint[on, 0]).tolist()) == [-1.0, 1.0]
    expected = MASS * 9.81 / (2.0 * np.cos(np.radians(30.0)))
    np.testing.assert_allclose(np.linalg.norm(st.mforce[on], axis=1), expected, rtol=1e-6)
    force, _ = sim.mesh_wall_forces()
    np.testing.assert_allclose(force[0], [0.0, 0.0, -MASS * 9.81], atol=1e-6 * MASS * 9.81)


def test_a_moving_mesh_does_the_work_the_energy_balance_says():
    """A mesh plane approaching from 1 cm (beyond the skin: wall motion must rebuild the
    candidates) at 0.5 m/s hits a resting sphere elastically: it leaves at 1 m/s, and
    the wall's work is its kinetic energy, as for a Plane."""
    mesh, plane, sim, psim = _pair_runs(
        dem.LinearSpring(kn=1e5), [0.2, 0.1, R + 0.01], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0],
        3500, 1e-5, gravity=(0.0, 0.0, 0.0), wall_vel=[0.0, 0.0, 0.5])
    ke = 0.5 * MASS * np.sum(sim.bodies.vel[0] ** 2)
    assert sim.bodies.vel[0, 2] == pytest.approx(1.0, rel=1e-3)
    assert sim.wall_work[0] == pytest.approx(ke, rel=1e-3)
    assert sim.wall_work[0] == pytest.approx(psim.wall_work[0], rel=1e-9)
    assert sim.mesh_walls[0].vertices[0, 2] == pytest.approx(0.5 * sim.time, rel=1e-9)


def test_a_turning_mesh_pushes_with_its_velocity_at_the_contact_point():
    """A paddle turning about the z axis hits a resting sphere 0.1 m from the axis: the
    sphere leaves at about twice the paddle's speed there, and the wall's work is the
    sphere's kinetic energy (the rotation's velocity enters the power)."""
    v = np.array([[0.05, 0, -0.05], [0.15, 0, -0.05], [0.15, 0, 0.05], [0.05, 0, 0.05]])
    paddle = dem.MeshWall(v, SQUARE_F, angular_velocity=[0.0, 0.0, 5.0], center=[0, 0, 0])
    b = dem.Bodies.spheres([[0.1, R + 0.002, 0.0]], radius=R, density=RHO)
    sim = dem.Simulation(b, dem.LinearSpring(kn=1e5), dt=1e-5, threads=1, walls=[paddle])
    sim.run(3000)
    assert sim.mesh_state.mtouch.sum() == 0
    ke = 0.5 * MASS * np.sum(b.vel[0] ** 2)
    assert np.linalg.norm(b.vel[0]) == pytest.approx(2 * 0.5, rel=0.05)
    assert sim.wall_work[0] == pytest.approx(ke, rel=2e-3)
    np.testing.assert_allclose(np.linalg.norm(paddle.face_normal, axis=1), 1.0, rtol=1e-12)
    assert np.arctan2(paddle.vertices[1, 1], paddle.vertices[1, 0]) == pytest.approx(
        5.0 * sim.time, rel=1e-9)


class _Servo:
    """Controller: moves the lid (mesh wall 0) to hold the force ``target`` [N] on it."""

    def __init__(self, target, gain):
        self.trigger = dem.Periodic(1)
        self.target, self.gain = target, gain

    def __call__(self, sim):
        force, _ = sim.mesh_wall_forces()
        sim.mesh_walls[0].velocity = np.array([0.0, 0.0, self.gain * (force[0, 2]
                                                                      - self.target)])


def test_a_servo_controller_holds_the_force_on_a_mesh_lid():
    lid = dem.MeshWall(SQUARE_V + [0.0, 0.0, 2 * R + 2e-4], SQUARE_F)
    b = dem.Bodies.spheres([[0.1, 0.2, R]], radius=R, density=RHO)
    b.add_plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    sim = dem.Simulation(b, dem.LinearSpring(kn=1e5, restitution=0.5), dt=1e-5,
                         damping=0.3, threads=1, walls=[lid], controllers=[_Servo(1.0, 0.02)])
    sim.run(5000)
    force, torque = sim.mesh_wall_forces()
    assert force[0, 2] == pytest.approx(1.0, rel=1e-3)
    assert sim.wall_forces()[1][2] == pytest.approx(-1.0, rel=1e-3)
    # the torque about the lid's centre (0, 0, z): the contact at (0.1, 0.2) pushes up
    np.testing.assert_allclose(torque[0], [0.2 * force[0, 2], -0.1 * force[0, 2], 0.0],
                               atol=1e-9)


def _box_scene(threads=1):
    """Spheres falling into a turning open box (a cube without its top)."""
    keep = [k for k in range(12) if CUBE_FACES[k].tolist() not in ([4, 5, 6], [4, 6, 7])]
    box = dem.MeshWall(CUBE_VERTICES * 0.1, CUBE_FACES[keep],
                       angular_velocity=[0.0, 0.0, 2.0], velocity=[0.0, 0.0, 0.01])
    rng = np.random.default_rng(3)
    g = np.stack(np.meshgrid(*[np.arange(3)] * 3, indexing="ij"), -1).reshape(-1, 3)
    pos = 0.0102 + 0.039 * g + 5e-4 * rng.standard_normal(g.shape)
    vel = [0.0, 0.0, -0.2] + 0.05 * rng.standard_normal(g.shape)
    b = dem.Bodies.spheres(pos, radius=R, density=RHO, vel=vel)
    return dem.Simulation(b, _law("linear"), dt=1e-5, gravity=[0, 0, -9.81], threads=threads,
                          walls=[box])


def _box_result(sim, n_steps=600):
    touching = 0  # the most mesh contacts at once, every 50 steps
    for _ in range(n_steps // 50):
        sim.run(50)
        touching = max(touching, int(sim.mesh_state.mtouch.sum()))
    force, torque = sim.mesh_wall_forces()
    return {"pos": sim.bodies.pos, "vel": sim.bodies.vel, "ang_vel": sim.bodies.ang_vel,
            "force": force, "torque": torque, "work": sim.wall_work,
            "vertices": sim.mesh_walls[0].vertices,
            "touching": np.array([touching])}


def test_thread_count_changes_no_bit(tmp_path):
    """One thread (the serial path) against two (the parallel path), in a process of
    two numba threads."""
    one = _box_result(_box_scene(threads=1))
    assert one["touching"][0] >= 5  # spheres on the bottom and the sides at once
    out = tmp_path / "two.npz"
    env = dict(os.environ, NUMBA_NUM_THREADS="2")
    subprocess.run([sys.executable, __file__, str(out)], check=True, env=env, timeout=900)
    two = np.load(out)
    for k, v in one.items():
        np.testing.assert_array_equal(v, two[k], err_msg=k)


def test_checkpoint_restart_changes_no_bit(tmp_path):
    first = _box_scene()
    first.run(300)
    save_checkpoint(first, tmp_path / "c.h5")
    whole = _box_result(first, 400)
    again = load_checkpoint(tmp_path / "c.h5", _law("linear"))
    assert again.mesh_walls[0].n_faces == 10
    for k, v in _box_result(again, 400).items():
        np.testing.assert_array_equal(v, whole[k], err_msg=k)


def test_output_frames_show_the_mesh_walls_where_they_are(tmp_path):
    """H5Writer frames hold the mesh walls' triangles at each frame, and the meshes'
    XDMF file describes them (meshio reads it back, the points moving)."""
    import meshio

    sim = _box_scene()
    path = tmp_path / "run.h5"
    with dem.io.H5Writer(path, every=100) as out:
        sim.observers.append(out)
        sim.run(200)
    with meshio.xdmf.TimeSeriesReader(str(tmp_path / "run_meshes.xdmf")) as reader:
        points, cells = reader.read_points_cells()
        frames = [reader.read_data(k) for k in range(reader.num_steps)]
    assert cells[0].type == "triangle" and cells[0].data.shape == (10, 3)
    assert len(frames) == 2
    last = frames[-1][1]["position"]
    np.testing.assert_array_equal(last, sim.mesh_walls[0].vertices)
    assert not np.array_equal(frames[0][1]["position"], last)  # it turned


def test_bad_mesh_walls_are_one_line_errors(tmp_path):
    disks = dem.Bodies.spheres([[0.0, 0.1]], radius=R, density=RHO)
    square = dem.MeshWall(SQUARE_V, SQUARE_F)
    with pytest.raises(ValueError, match="^mesh walls need a 3D scene of spheres: this "
                                         "scene is 2D$"):
        dem.Simulation(disks, _law("linear"), dt=1e-5, walls=[square])
    balls = dem.Bodies.spheres([[0.0, 0.0, 0.1]], radius=R, density=RHO)
    with pytest.raises(ValueError, match="^walls must be dem.MeshWall objects, got ndarray$"):
        dem.Simulation(balls, _law("linear"), dt=1e-5, walls=[SQUARE_V])
    with pytest.raises(ValueError, match="^mesh wall mat_id must be an integer >= 0"):
        dem.MeshWall(SQUARE_V, SQUARE_F, mat_id=-1)
    square.write(tmp_path / "open.stl")
    with pytest.raises(ValueError, match=r"open\.stl is not watertight: 4 open edges$"):
        dem.MeshWall.from_file(tmp_path / "open.stl", require_watertight=True)


if __name__ == "__main__":  # the two-thread run of test_thread_count_changes_no_bit
    np.savez(sys.argv[1], **_box_result(_box_scene(threads=2)))
