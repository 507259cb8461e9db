"""The macro problem on scikit-fem: quasi-static, Gauss-point data, small or finite.

:class:`Macro` holds a mesh and a vector basis and turns Gauss-point arrays into the
finite element quantities of a Newton iteration. Its ``kinematics`` is a choice:

``"small"``
    The mesh never moves. The micro models get the strain increment ``sym grad du``;
    the internal force is ``r_a = int sigma : eps(v_a) dV`` and the stiffness
    ``K_ab = int eps(v_a) : C : eps(v_b) dV``.
``"finite"``
    Updated Lagrangian. Every quantity lives on the current configuration
    ``x = X + u``: the micro models get the displacement-gradient increment on the
    configuration of the last converged step, ``G = grad_{x_n} du`` (not
    symmetrised: it carries the spin), and return the Cauchy stress in the current
    frame; the internal force is ``r_a = int sigma : grad_x v_a dv`` and the Newton
    matrix adds to the material part the geometric (initial-stress) one
    (:func:`hmm.tensors.spatial_tangent`). Integrals over the current configuration
    are evaluated on the initial mesh through ``grad_x = grad_X F^-1`` and
    ``dv = det F dV``, ``F = I + grad_X u``: the same integrals on the isoparametric
    image of the mesh, curved edges of quadratic elements included, with no drift
    from moving the mesh step after step. Pressures follow the deformed boundary
    (with their load stiffness) unless they are dead loads; tractions and body
    forces are per unit reference area and volume unless stated per current one.

Gauss points are numbered ``e * n_qp + q`` (element ``e``, quadrature point ``q``),
the order of a farm; they are material points, carried by the motion. 2D is plane
strain. Linear forms follow scikit-fem: decorated pure functions, with Gauss-point
data reaching them by keyword (``w.sigma``, ``w.J``). The Newton matrix and the
follower pressures' load stiffness are array products over all elements and pairs of
local basis functions at once (:func:`_assemble`); skfem's ``BilinearForm`` would call
a Python form per pair, 3,600 times an assembly of hex20 (``tests/hmm/test_finite.py``
checks the two agree to round-off).
"""

import numpy as np
from scipy.sparse import coo_matrix
from skfem import (
    Basis,
    BilinearForm,
    ElementHex1,
    ElementHex2,
    ElementHexS2,
    ElementQuad1,
    ElementQuad2,
    ElementQuadS2,
    ElementTetP1,
    ElementTetP2,
    ElementTriP1,
    ElementTriP2,
    ElementVector,
    FacetBasis,
    LinearForm,
    MeshHex,
    MeshQuad,
    MeshTet,
    MeshTri,
    asm,
)
from skfem.helpers import ddot, dot, mul, sym_grad, trace

from .tensors import log_strain, spatial_tangent

#: element name -> (mesh class, element class, quadrature order): 2x2 Gauss points
#: on bilinear quadrilaterals, 3x3 on biquadratic (9-node) ones, 2x2 on 8-node
#: serendipity ones (reduced integration, as YADE's FEMxDEM), 1 / 3 on linear /
#: quadratic triangles, 2x2x2 on trilinear hexahedra and on 20-node serendipity ones
#: (reduced, as YADE's FEMxDEM), 3x3x3 on triquadratic (27-node) ones, 1 on linear
#: tetrahedra and 4 on quadratic (10-node) ones
ELEMENTS = {
    "quad1": (MeshQuad, ElementQuad1, 3),
    "quad2": (MeshQuad, ElementQuad2, 5),
    "quad8": (MeshQuad, ElementQuadS2, 3),
    "tri1": (MeshTri, ElementTriP1, 1),
    "tri2": (MeshTri, ElementTriP2, 2),
    "hex1": (MeshHex, ElementHex1, 3),
    "tet1": (MeshTet, ElementTetP1, 1),
    "hex20": (MeshHex, ElementHexS2, 3),
    "hex27": (MeshHex, ElementHex2, 5),
    "tet10": (MeshTet, ElementTetP2, 2),
}

#: quadratic quadrilaterals and hexahedra: the quadrature order of reduced (2 points
#: per axis) and full (3) integration; the default is the one in :data:`ELEMENTS`
INTEGRATION = {name: {"reduced": 3, "full": 5}
               for name in ("quad2", "quad8", "hex20", "hex27")}


@LinearForm
def _internal(v, w):
    return ddot(w.sigma, sym_grad(v))


@LinearForm
def _pressure(v, w):
    return -w.p * dot(w.n, v)


@LinearForm
def _vector_load(v, w):
    return dot(w.t, v)


# --------------------------------------------------------------------------- finite
# w.Finv (d, d, ...) and w.J (...) describe the current configuration at the
# quadrature points of the initial mesh: grad_x v = grad_X v F^-1, dv = J dV.
@LinearForm
def _internal_finite(v, w):
    return ddot(w.sigma, mul(v.grad, w.Finv)) * w.J


@LinearForm
def _follower_pressure(v, w):
    # n da = J F^-T N dA (Nanson): w.m = J F^-T N
    return -w.p * dot(w.m, v)


@BilinearForm
def _current_area_stiffness(u, v, w):
    # d|n da| = (tr g - n.g n) da for a traction per unit current area
    g = mul(u.grad, w.Finv)
    da = np.sqrt(dot(w.m, w.m))
    gm = np.einsum("ij...,j...->i...", g, w.m)
    change = trace(g) * da - dot(w.m, gm) / da
    return dot(w.t, v) * change


@LinearForm
def _current_volume_load(v, w):
    return dot(w.t, v) * w.J


@BilinearForm
def _current_volume_stiffness(u, v, w):
    return dot(w.t, v) * trace(mul(u.grad, w.Finv)) * w.J


#: the kinematics a Macro offers
KINEMATICS = ("small", "finite")


def _inverse_and_det(f):
    """F^-1 and det F of (d, d, ...) arrays."""
    m = np.moveaxis(f, (0, 1), (-2, -1))
    return np.moveaxis(np.linalg.inv(m), (-2, -1), (0, 1)), np.linalg.det(m)


def _local_fields(basis):
    """The values (n, d, ne, nq) and gradients (n, d, d, ne, nq) of the ``n`` local
    basis functions of a vector basis at its quadrature points, kept on the basis."""
    got = getattr(basis, "_hmm_local", None)
    if got is None:
        got = (np.array([np.asarray(f[0]) for f in basis.basis]),
               np.array([np.asarray(f[0].grad) for f in basis.basis]))
        basis._hmm_local = got
    return got


def _assemble(basis, local):
    """The sparse matrix (rows: test functions, columns: trial ones, as skfem's
    ``asm``) of element matrices ``local`` (ne, n, n), ``local[e, i, j]`` for the test
    function ``i`` and the trial function ``j`` of element ``e``.

    The bilinear forms of the Newton matrix are written as array products over all
    elements and basis pairs at once (:meth:`Macro.stiffness`,
    :meth:`Macro.pressure_stiffness`): skfem's ``BilinearForm`` calls its Python form
    once per pair of local functions, 3,600 times an assembly for hex20.
    """
    dofs = basis.element_dofs  # (n, ne)
    rows = np.broadcast_to(dofs.T[:, :, None], local.shape).ravel()
    cols = np.broadcast_to(dofs.T[:, None, :], local.shape).ravel()
    return coo_matrix((local.ravel(), (rows, cols)), shape=(basis.N, basis.N)).tocsr()


def structured_mesh(element, size, cells):
    """A rectangle (2D) or box (3D) ``[0, size]`` split into ``cells`` per axis, with
    the boundaries ``left``/``right`` (x), ``bottom``/``top`` (y) and
    ``front``/``back`` (z in 3D)."""
    return tensor_mesh(element, [np.linspace(0.0, float(s), int(n) + 1)
                                 for s, n in zip(size, cells, strict=True)])


def tensor_mesh(element, edges):
    """The rectangle (2D) or box (3D) whose elements have the edges ``edges`` [m] along
    each axis (increasing coordinates: a graded mesh), with the boundaries of
    :func:`structured_mesh`.

    >>> m = tensor_mesh("quad1", [[0.0, 0.1, 0.4], [0.0, 0.03, 0.2]])
    >>> sorted(float(y) for y in set(m.p[1]))
    [0.0, 0.03, 0.2]
    """
    mesh_cls = ELEMENTS[element][0]
    return mesh_cls.init_tensor(*[np.asarray(e, dtype=np.float64) for e in edges]) \
        .with_defaults()


class Macro:
    """A mesh, a vector basis of ``element`` on it, and the Gauss-point layout.

    Parameters
    ----------
    mesh : skfem.Mesh
        With named boundaries (``mesh.boundaries``) for loads and supports.
    element : str
        One of :data:`ELEMENTS`.
    kinematics : str
        ``"small"`` or ``"finite"`` (see the module docstring).
    integration : str, optional
        ``"reduced"`` (2 Gauss points per axis) or ``"full"`` (3) for the quadratic
        quadrilaterals and hexahedra (:data:`INTEGRATION`); None: the element's
        default (:data:`ELEMENTS`: reduced for quad8 and hex20, full for quad2 and
        hex27).
    """

    def __init__(self, mesh, element="quad1", kinematics="small", integration=None):
        if element not in ELEMENTS:
            raise ValueError(f"element must be one of {', '.join(ELEMENTS)}, got {element!r}")
        if kinematics not in KINEMATICS:
            raise ValueError(f"kinematics must be \"small\" or \"finite\", got "
                             f"{kinematics!r}")
        self.kinematics = kinematics
        self.finite = kinematics == "finite"
        mesh_cls, elem_cls, order = ELEMENTS[element]
        if integration is not None:
            if element not in INTEGRATION:
                raise ValueError(f"integration applies to {', '.join(INTEGRATION)}, "
                                 f"not to {element!r}")
            if integration not in INTEGRATION[element]:
                raise ValueError(f"integration must be \"reduced\" or \"full\", got "
                                 f"{integration!r}")
            order = INTEGRATION[element][integration]
        if not isinstance(mesh, mesh_cls):
            raise TypeError(f"element {element!r} needs a {mesh_cls.__name__}, "
                             f"got a {type(mesh).__name__}")
        self.mesh = mesh
        self.element = element
        self.dim = mesh.dim()
        self.elem = ElementVector(elem_cls())
        self.order = order
        self.basis = Basis(mesh, self.elem, intorder=order)
        self._facet_bases = {}  # boundary name -> FacetBasis, built on first use
        self.n_elems = self.basis.nelems
        self.n_qp = self.basis.X.shape[-1]
        self.n_gp = self.n_elems * self.n_qp
        self.n_dofs = self.basis.N

    # ------------------------------------------------------------------ layout
    def to_gp(self, field):
        """(..., n_elems, n_qp) -> (n_gp, ...)."""
        a = np.moveaxis(np.asarray(field), (-2, -1), (0, 1))
        return a.reshape((self.n_gp,) + a.shape[2:])

    def from_gp(self, a):
        """(n_gp, ...) -> (..., n_elems, n_qp)."""
        a = np.asarray(a).reshape((self.n_elems, self.n_qp) + np.shape(a)[1:])
        return np.moveaxis(a, (0, 1), (-2, -1))

    def gauss_points(self, u=None):
        """Coordinates of the Gauss points (n_gp, d) [m]: initial, or with ``u`` (and
        finite kinematics) current."""
        x = self.to_gp(self.basis.mapping.F(self.basis.X))
        if u is not None and self.finite:
            x = x + self.to_gp(self.basis.interpolate(u))
        return x

    def weights(self, u=None):
        """Integration weight (volume) of each Gauss point (n_gp,) [m^d]: initial, or
        with ``u`` (and finite kinematics) current."""
        w = self.to_gp(self.basis.dx)
        if u is not None and self.finite:
            w = w * np.linalg.det(self.deformation(u))
        return w

    # ------------------------------------------------------------------ kinematics
    def strain(self, u):
        """Small strain ``sym grad u`` at the Gauss points (n_gp, d, d)."""
        return self.to_gp(sym_grad(self.basis.interpolate(u)))

    def total_strain(self, u):
        """The strain of the displacement ``u`` at the Gauss points (n_gp, d, d):
        ``sym grad u`` (small), or Hencky's logarithmic strain ``ln V`` (finite)."""
        if not self.finite:
            return self.strain(u)
        return log_strain(self.deformation(u))

    def current_points(self, u):
        """Vertex coordinates of the deformed mesh (n_vertices, d) [m]: initial ones
        under small kinematics."""
        x = self.mesh.p.T.copy()
        if self.finite:
            x += self.nodal_displacement(u)
        return x

    def deformation(self, u):
        """The deformation gradient ``F = I + grad_X u`` at the Gauss points
        (n_gp, d, d)."""
        return self.to_gp(self._deformation(u))

    def _deformation(self, u):
        return self.basis.interpolate(u).grad + np.eye(self.dim)[:, :, None, None]

    def increment_gradient(self, u, du):
        """What the micro models get for the increment ``du`` from the converged
        displacement ``u`` (n_gp, d, d): ``sym grad du`` (small), or
        ``grad_{x_n} du = grad_X du F(u)^-1`` (finite, not symmetrised)."""
        if not self.finite:
            return self.strain(du)
        finv, _ = _inverse_and_det(self._deformation(u))
        return self.to_gp(mul(self.basis.interpolate(du).grad, finv))

    def configuration(self, u):
        """``(F^-1, det F)`` at the quadrature points, as (d, d, ne, nq), (ne, nq)."""
        return _inverse_and_det(self._deformation(u))

    # ------------------------------------------------------------------ forms
    def internal_force(self, sigma, u=None):
        """``int sigma : eps(v) dV`` (small), or ``int sigma : grad_x v dv`` on the
        configuration of ``u`` (finite), for Cauchy stresses (n_gp, d, d) [N]."""
        if u is None or not self.finite:
            return asm(_internal, self.basis, sigma=self.from_gp(sigma))
        finv, jac = self.configuration(u)
        return asm(_internal_finite, self.basis, sigma=self.from_gp(sigma), Finv=finv,
                   J=jac)

    def stiffness(self, tangent, u=None, sigma=None):
        """``int eps(v) : C : eps(du) dV`` for tangents (n_gp, d, d, d, d) (small), or
        the updated-Lagrangian Newton matrix on the configuration of ``u``, material
        and geometric parts, which needs the stresses ``sigma`` too (finite).
        Sparse."""
        _, grads = _local_fields(self.basis)
        if u is None or not self.finite:
            g = 0.5 * (grads + np.swapaxes(grads, 1, 2))  # sym grad
            c, dx = self.from_gp(tangent), self.basis.dx
        else:
            if sigma is None:
                raise ValueError("the finite-strain stiffness needs the stresses")
            finv, jac = self.configuration(u)
            g = np.einsum("nac...,cb...->nab...", grads, finv)  # grad_x = grad_X F^-1
            c, dx = self.from_gp(spatial_tangent(sigma, tangent)), self.basis.dx * jac
        cg = np.einsum("abkl...,jkl...->jab...", c, g)
        return _assemble(self.basis, np.einsum("iabeq,jabeq,eq->eij", g, cg, dx))

    def _facets(self, boundary):
        """The facet basis of a boundary on the initial mesh, built once: the forms
        of every load, dead or following, are integrated there."""
        if boundary not in self.mesh.boundaries:
            raise KeyError(boundary)
        if boundary not in self._facet_bases:
            self._facet_bases[boundary] = FacetBasis(
                self.mesh, self.elem, facets=self.mesh.boundaries[boundary],
                intorder=self.order)
        return self._facet_bases[boundary]

    def _facet_current(self, fb, u):
        """``(F^-1, J F^-T N)`` at the quadrature points of facets ``fb``."""
        finv, jac = _inverse_and_det(fb.interpolate(u).grad
                                     + np.eye(self.dim)[:, :, None, None])
        m = jac * np.einsum("ki...,k...->i...", finv, np.asarray(fb.normals))
        return finv, m

    def pressure_force(self, boundary, pressure, u=None):
        """Nodal forces [N] of a pressure [Pa] (compressive, positive) on a boundary:
        on the initial boundary, or (``u`` given, finite kinematics) on the deformed
        one, normal to it (a follower load)."""
        fb = self._facets(boundary)
        if u is None or not self.finite:
            return asm(_pressure, fb, p=float(pressure))
        _, m = self._facet_current(fb, u)
        return asm(_follower_pressure, fb, p=float(pressure), m=m)

    def pressure_stiffness(self, boundary, pressure, u):
        """``d f / d u`` of :meth:`pressure_force` on the deformed boundary (sparse):
        the load stiffness of a follower pressure."""
        fb = self._facets(boundary)
        finv, m = self._facet_current(fb, u)
        # d(n da) = (tr g I - g^T) n da, g = grad_x du: the form -p (tr g m - g^T m).v
        values, grads = _local_fields(fb)
        g = np.einsum("nac...,cb...->nab...", grads, finv)
        mv = np.einsum("a...,ia...->i...", m, values)
        gtm = np.einsum("jba...,b...->ja...", g, m)
        dx = fb.dx
        local = np.einsum("jaaeq,ieq,eq->eij", g, mv, dx) \
            - np.einsum("jaeq,iaeq,eq->eij", gtm, values, dx)
        return _assemble(fb, -float(pressure) * local)

    def traction_force(self, boundary, traction, u=None):
        """Nodal forces [N] of a traction vector (d,) [Pa] on a boundary: per unit
        initial area, or (``u`` given, finite kinematics) per unit current area."""
        fb = self._facets(boundary)
        t = np.asarray(traction, dtype=np.float64)[:, None, None] * np.ones(fb.dx.shape)
        if u is None or not self.finite:
            return asm(_vector_load, fb, t=t)
        _, m = self._facet_current(fb, u)
        return asm(_vector_load, fb, t=t * np.sqrt(dot(m, m)))

    def traction_stiffness(self, boundary, traction, u):
        """``d f / d u`` of a traction per unit current area (sparse)."""
        fb = self._facets(boundary)
        finv, m = self._facet_current(fb, u)
        t = np.asarray(traction, dtype=np.float64)[:, None, None] * np.ones(fb.dx.shape)
        return asm(_current_area_stiffness, fb, t=t, m=m, Finv=finv)

    def body_force(self, density_g, u=None):
        """Nodal forces [N] of a body force density (d,) [N/m^3]: per unit initial
        volume, or (``u`` given, finite kinematics) per unit current volume."""
        b = np.asarray(density_g, dtype=np.float64)[:, None, None]
        t = b * np.ones(self.basis.dx.shape)
        if u is None or not self.finite:
            return asm(_vector_load, self.basis, t=t)
        _, jac = self.configuration(u)
        return asm(_current_volume_load, self.basis, t=t, J=jac)

    def body_force_stiffness(self, density_g, u):
        """``d f / d u`` of a body force per unit current volume (sparse)."""
        b = np.asarray(density_g, dtype=np.float64)[:, None, None]
        finv, jac = self.configuration(u)
        return asm(_current_volume_stiffness, self.basis,
                   t=b * np.ones(self.basis.dx.shape), Finv=finv, J=jac)

    def dofs(self, boundary, component):
        """Degrees of freedom of displacement ``component`` (0..d-1) on a boundary."""
        if boundary not in self.mesh.boundaries:
            raise KeyError(boundary)
        return np.asarray(self.basis.get_dofs(boundary).all(f"u^{component + 1}"))

    def nodal_displacement(self, u):
        """Displacement at the mesh vertices (n_vertices, d) [m]."""
        return u[self.basis.nodal_dofs].T
