"""The part of :class:`dem.Simulation` that runs triangle-mesh walls.

``Simulation(bodies, law, walls=[mesh_wall, ...])`` makes each :class:`dem.MeshWall`
a wall of the time step (3D sphere scenes). The walls become blocks of one combined
mesh that the sphere loop moves and reads (:mod:`dem.contact.mesh_contacts`); each
wall object's ``vertices``, ``face_normal`` and ``center`` are then views of it, so
they follow the motion. A wall's ``velocity`` and ``angular_velocity`` are read at the
start of every chunk of steps, so a controller may set them (a servo). Contacts go
through the contact model's ``"pw"`` law, with the parameters of the sphere's material
and the wall's ``mat_id``.

Candidates: when the Verlet list is built, the faces whose boxes grown by the skin
meet a sphere's box (:func:`~dem.meshwall_kernels.faces_near_spheres`); they hold
while spheres move less than half the skin and walls less than half the skin (less
the inner list's skin), which the loop checks. Rows carry their state across builds
by their key (sphere, face).
"""

import numpy as np

from .contact.mesh_contacts import MeshContactState, MeshLoop, MeshMotion
from .meshwall import MeshWall, face_grid
from .meshwall_kernels import MeshArrays, faces_near_spheres
from .neighbors import carry_history
from .shapes import Shape

#: the snapshot keys of the mesh geometry that moves (the rest is fixed by the walls)
_MOVING = ("vertices", "face_normal", "center", "vert_ref")


def _i8(*shape):
    return np.zeros(shape, np.int64)


def _f8(*shape):
    return np.zeros(shape, np.float64)


def _empty_state(m, n_hist):
    return MeshContactState(_i8(m, 2), _f8(m, n_hist), np.zeros(m, np.uint8), _f8(m, 3),
                            _f8(m, 3), _f8(m, 3), _f8(m))


def _combined(walls):
    """One MeshArrays of every wall (rows offset wall by wall), and the wall of each
    vertex and face."""
    parts = {k: [] for k in MeshArrays._fields}
    vw, fw = [], []
    nv = nf = ne = n_ef = n_vf = 0
    for w, m in enumerate(walls):
        a = m.arrays
        parts["vertices"].append(a.vertices)
        parts["faces"].append(a.faces + nv)
        parts["face_normal"].append(a.face_normal)
        parts["face_edges"].append(a.face_edges + ne)
        parts["edge_face_ptr"].append(a.edge_face_ptr[(0 if w == 0 else 1):] + n_ef)
        parts["edge_face_idx"].append(a.edge_face_idx + nf)
        parts["vertex_face_ptr"].append(a.vertex_face_ptr[(0 if w == 0 else 1):] + n_vf)
        parts["vertex_face_idx"].append(a.vertex_face_idx + nf)
        vw.append(np.full(a.vertices.shape[0], w, np.int64))
        fw.append(np.full(a.faces.shape[0], w, np.int64))
        nv += a.vertices.shape[0]
        nf += a.faces.shape[0]
        ne += m.edges.shape[0]
        n_ef += a.edge_face_idx.shape[0]
        n_vf += a.vertex_face_idx.shape[0]
    mesh = MeshArrays(*(np.ascontiguousarray(np.concatenate(parts[k]))
                        for k in MeshArrays._fields))
    return mesh, np.concatenate(vw), np.concatenate(fw)


def _turn(omega, dt):
    """Rotation matrix (3, 3) of ``omega * dt`` (Rodrigues' formula)."""
    angle = float(np.linalg.norm(omega)) * dt
    if angle == 0.0:
        return np.eye(3)
    k = omega / np.linalg.norm(omega)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * kx + (1.0 - np.cos(angle)) * (kx @ kx)


def walls_from_snapshot(snap):
    """The :class:`MeshWall` objects of a snapshot's ``mesh.*`` arrays (checkpoints),
    at their saved positions and velocities (an empty list if it has none)."""
    if "mesh.faces" not in snap:
        return []
    vw, fw = snap["mesh.vert_wall"], snap["mesh.face_wall"]
    out = []
    for w in range(snap["mesh.mat_id"].shape[0]):
        rows = np.nonzero(vw == w)[0]
        faces = snap["mesh.faces"][fw == w] - (rows[0] if rows.size else 0)
        out.append(MeshWall(snap["mesh.vertices"][rows], faces,
                            velocity=snap["mesh.velocity"][w],
                            angular_velocity=snap["mesh.ang_vel"][w],
                            center=snap["mesh.center"][w],
                            mat_id=int(snap["mesh.mat_id"][w])))
    return out


class MeshScene:
    """Mesh walls of a :class:`dem.Simulation` (a base of it, which provides the
    bodies, the neighbour list's skin and the contact model)."""

    def _mesh_setup(self, walls, periodic):
        """Check the walls and combine them (module docstring)."""
        walls = list(walls)
        for m in walls:
            if not isinstance(m, MeshWall):
                raise ValueError(f"walls must be dem.MeshWall objects, got "
                                 f"{type(m).__name__}")
        self.mesh_walls = walls
        self.has_mesh = bool(walls)
        n_hist = self.model.n_hist
        self._mstart = _i8(self.bodies.n + 1)
        self._mflag = _i8(0)
        self._msum = _f8(0, 6)
        if not walls:
            self._mesh = MeshArrays(_f8(0, 3), _i8(0, 3), _f8(0, 3), _i8(0, 3), _i8(1),
                                    _i8(0), _i8(1), _i8(0))
            self._vert_wall, self._face_wall = _i8(0), _i8(0)
            self._mcenter, self._vert_ref, self._mmat = _f8(0, 3), _f8(0, 3), _i8(0)
            self.mesh_state = _empty_state(0, n_hist)
            return
        if self.dim != 3:
            raise ValueError("mesh walls need a 3D scene of spheres: this scene is 2D")
        if self.shaped:
            raise ValueError("mesh walls act on spheres only: this scene has "
                             "non-spherical shapes")
        if periodic or self.cell is not None:
            raise ValueError("mesh walls do not work with periodic boundaries")
        if len({id(m) for m in walls}) != len(walls):
            raise ValueError("a mesh wall is given twice in walls")
        self._mesh, self._vert_wall, self._face_wall = _combined(walls)
        self._mcenter = np.array([m.center for m in walls], np.float64)
        self._mmat = np.array([m.mat_id for m in walls], np.int64)
        self._vert_ref = self._mesh.vertices.copy()
        self.mesh_state = _empty_state(0, n_hist)
        self._mesh_views()

    def _mesh_views(self):
        """Make each wall's vertices, normals and centre views of the combined mesh."""
        for w, m in enumerate(self.mesh_walls):
            vrows = np.nonzero(self._vert_wall == w)[0]
            frows = np.nonzero(self._face_wall == w)[0]
            m.vertices = self._mesh.vertices[vrows[0]:vrows[-1] + 1]
            m.face_normal = self._mesh.face_normal[frows[0]:frows[-1] + 1]
            m.center = self._mcenter[w]
            m._grids = {}

    def _mesh_sync(self):
        """After a chunk: the walls' bounding boxes and cached grids follow them."""
        for m in self.mesh_walls:
            m.bounds = np.array([m.vertices.min(axis=0), m.vertices.max(axis=0)])
            m._grids = {}

    def _mesh_n_mat(self):
        """Materials the mesh walls use (rows of the parameter tables)."""
        return int(self._mmat.max()) + 1 if self._mmat.size else 0

    def _mesh_loop(self):
        """The :class:`MeshLoop` of the next chunk: velocities read from the walls."""
        walls = self.mesh_walls
        vel = np.array([m.velocity for m in walls], np.float64).reshape(-1, 3)
        omega = np.array([m.angular_velocity for m in walls], np.float64).reshape(-1, 3)
        if not (np.all(np.isfinite(vel)) and np.all(np.isfinite(omega))):
            raise ValueError("mesh wall velocity and angular_velocity must be finite")
        turn = np.array([_turn(o, self.dt) for o in omega]).reshape(-1, 3, 3)
        moving = np.where(np.any(omega != 0.0, axis=1), 2,
                          np.where(np.any(vel != 0.0, axis=1), 1, 0)).astype(np.int64)
        motion = MeshMotion(self._vert_wall, self._face_wall, self._mcenter, vel, omega,
                            turn, moving, self._vert_ref, self._mmat)
        if self._msum.shape[0] != self.bodies.n:
            self._msum = _f8(self.bodies.n, 6)
        return MeshLoop(self._mesh, motion, self.mesh_state, self._mstart, self._mflag,
                        self._msum)

    def _mesh_rebuild(self):
        """Candidate rows (sphere, face) for the new Verlet list; state carried by key."""
        b = self.bodies
        if not self.has_mesh:
            if self._mstart.shape[0] != b.n + 1:
                self._mstart = _i8(b.n + 1)
            return
        sph = np.nonzero(b.kind == Shape.SPHERE)[0]
        grid = face_grid(self._mesh.vertices, self._mesh.faces, self.neighbors.skin)
        pos = np.ascontiguousarray(b.pos[sph])
        rad = np.ascontiguousarray(b.radius[sph])
        ptr = _i8(sph.size + 1)
        faces = _i8(max(16, 4 * sph.size))
        need = faces_near_spheres(pos, rad, grid, ptr, faces)
        if need > faces.shape[0]:
            faces = _i8(need)
            faces_near_spheres(pos, rad, grid, ptr, faces)
        rows = np.column_stack([np.repeat(sph, np.diff(ptr)), faces[:need]])
        rows = np.ascontiguousarray(rows, dtype=np.int64)
        old = self.mesh_state
        new = _empty_state(rows.shape[0], self.model.n_hist)
        packed_old = np.column_stack([old.mhist, old.mtouch, old.mpoint, old.mforce,
                                      old.mtorque, old.mpower])
        packed = np.zeros((rows.shape[0], packed_old.shape[1]))
        carry_history(old.mrows, packed_old, rows, packed)
        h = old.mhist.shape[1]
        new.mrows[:] = rows
        new.mhist[:] = packed[:, :h]
        new.mtouch[:] = packed[:, h]
        new.mpoint[:] = packed[:, h + 1:h + 4]
        new.mforce[:] = packed[:, h + 4:h + 7]
        new.mtorque[:] = packed[:, h + 7:h + 10]
        new.mpower[:] = packed[:, h + 10]
        self.mesh_state = new
        self._mflag = _i8(rows.shape[0])
        self._mstart = _i8(b.n + 1)
        np.cumsum(np.bincount(rows[:, 0], minlength=b.n), out=self._mstart[1:])
        self._vert_ref[:] = self._mesh.vertices

    # ------------------------------------------------------------------ public
    def mesh_wall_forces(self):
        """Total contact force [N] on each mesh wall and its torque [N m] about the
        wall's centre, from the last force evaluation: ``(force, torque)``, both
        (n_walls, 3), in the order of ``walls``."""
        self.prime()
        nw = len(self.mesh_walls)
        force, torque = _f8(nw, 3), _f8(nw, 3)
        st = self.mesh_state
        wall = self._face_wall[st.mrows[:, 1]]
        for w in range(nw):
            rows = wall == w
            f = -st.mforce[rows]  # the wall's reaction
            force[w] = f.sum(axis=0)
            torque[w] = np.cross(st.mpoint[rows] - self._mcenter[w], f).sum(axis=0)
        return force, torque

    def mesh_contacts(self):
        """The touching sphere-mesh contacts of the last force evaluation, one row
        each: ``sphere`` (n,), ``wall`` (n,) its index in ``mesh_walls``, ``mat_id``
        (n,) the wall's material, ``point`` (n, 3) [m] the middle of the overlap,
        ``force`` (n, 3) [N] on the sphere, ``hist`` (n, h) the law's history rows
        (copies; empty without mesh walls)."""
        self.prime()
        st = self.mesh_state
        t = st.mtouch == 1
        wall = self._face_wall[st.mrows[t, 1]] if self.has_mesh else _i8(0)
        return {"sphere": st.mrows[t, 0].copy(), "wall": wall,
                "mat_id": self._mmat[wall] if self.has_mesh else _i8(0),
                "point": st.mpoint[t].copy(), "force": st.mforce[t].copy(),
                "hist": st.mhist[t].copy()}

    # ------------------------------------------------------------------ state
    def _mesh_state_arrays(self):
        """The ``mesh.*`` arrays of :meth:`state_arrays` (none without mesh walls)."""
        if not self.has_mesh:
            return {}
        src = {"mesh." + k: v for k, v in self.mesh_state._asdict().items()}
        src.update({"mesh.vertices": self._mesh.vertices, "mesh.faces": self._mesh.faces,
                    "mesh.face_normal": self._mesh.face_normal, "mesh.center": self._mcenter,
                    "mesh.vert_ref": self._vert_ref, "mesh.vert_wall": self._vert_wall,
                    "mesh.face_wall": self._face_wall, "mesh.mat_id": self._mmat,
                    "mesh.mstart": self._mstart})
        loop = self._mesh_loop()
        src["mesh.velocity"] = loop.walls.velocity
        src["mesh.ang_vel"] = loop.walls.ang_vel
        return src

    def _mesh_restore(self, snap):
        """Set the mesh state of a snapshot (:meth:`restore`)."""
        if not self.has_mesh:
            if "mesh.faces" in snap:
                raise ValueError("snapshot of another scene: it has mesh walls")
            return
        if "mesh.faces" not in snap or not np.array_equal(snap["mesh.faces"],
                                                          self._mesh.faces):
            raise ValueError("snapshot of another scene: the mesh walls differ")
        arrays = {"vertices": self._mesh.vertices, "face_normal": self._mesh.face_normal,
                  "center": self._mcenter, "vert_ref": self._vert_ref}
        for k in _MOVING:
            np.copyto(arrays[k], snap["mesh." + k])
        self.mesh_state = MeshContactState(*(snap["mesh." + k].copy()
                                             for k in MeshContactState._fields))
        self._mstart = snap["mesh.mstart"].copy()
        self._mflag = _i8(self.mesh_state.mrows.shape[0])
        for w, m in enumerate(self.mesh_walls):
            m.velocity = snap["mesh.velocity"][w].copy()
            m.angular_velocity = snap["mesh.ang_vel"][w].copy()
        self._mesh_sync()
