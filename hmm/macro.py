"""The macro problem on scikit-fem: small-strain, quasi-static, Gauss-point data.

:class:`Macro` holds a mesh and a vector basis and turns Gauss-point arrays into the
finite element quantities of a Newton iteration:

* the strain increment at every Gauss point, ``sym grad du`` -> (n_gp, d, d);
* the internal force ``r_a = int sigma : eps(v_a)`` from stresses (n_gp, d, d);
* the stiffness ``K_ab = int eps(v_a) : C : eps(v_b)`` from tangents (n_gp, d,d,d,d);
* external forces: pressure and traction on named boundaries, body force.

Gauss points are numbered ``e * n_qp + q`` (element ``e``, quadrature point ``q``),
the order of a farm. 2D is plane strain. Weak forms follow scikit-fem: decorated pure
functions, with Gauss-point data reaching them by keyword (``w.sigma``, ``w.C``).
"""

import numpy as np
from skfem import (
    Basis,
    BilinearForm,
    ElementHex1,
    ElementQuad1,
    ElementQuad2,
    ElementQuadS2,
    ElementTetP1,
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
from skfem.helpers import ddot, dot, sym_grad

#: element name -> (mesh class, element class, quadrature order): 2x2 Gauss points
#: on bilinear quadrilaterals, 3x3 on biquadratic (9-node) ones, 2x2 on 8-node
#: serendipity ones (reduced integration, as YADE's FEMxDEM), 1 / 3 on linear /
#: quadratic triangles, 2x2x2 on trilinear hexahedra, 1 on linear tetrahedra
ELEMENTS = {
    "quad1": (MeshQuad, ElementQuad1, 3),
    "quad2": (MeshQuad, ElementQuad2, 5),
    "quad8": (MeshQuad, ElementQuadS2, 3),
    "tri1": (MeshTri, ElementTriP1, 1),
    "tri2": (MeshTri, ElementTriP2, 2),
    "hex1": (MeshHex, ElementHex1, 3),
    "tet1": (MeshTet, ElementTetP1, 1),
}


@BilinearForm
def _stiffness(u, v, w):
    return ddot(sym_grad(v), np.einsum("ijkl...,kl...->ij...", w.C, sym_grad(u)))


@LinearForm
def _internal(v, w):
    return ddot(w.sigma, sym_grad(v))


@LinearForm
def _pressure(v, w):
    return -w.p * dot(w.n, v)


@LinearForm
def _vector_load(v, w):
    return dot(w.t, v)


def structured_mesh(element, size, cells):
    """A rectangle (2D) or box (3D) ``[0, size]`` split into ``cells`` per axis, with
    the boundaries ``left``/``right`` (x), ``bottom``/``top`` (y) and
    ``front``/``back`` (z in 3D)."""
    mesh_cls = ELEMENTS[element][0]
    axes = [np.linspace(0.0, float(s), int(n) + 1) for s, n in zip(size, cells, strict=True)]
    return mesh_cls.init_tensor(*axes).with_defaults()


class Macro:
    """A mesh, a vector basis of ``element`` on it, and the Gauss-point layout.

    Parameters
    ----------
    mesh : skfem.Mesh
        With named boundaries (``mesh.boundaries``) for loads and supports.
    element : str
        One of :data:`ELEMENTS`.
    """

    def __init__(self, mesh, element="quad1"):
        if element not in ELEMENTS:
            raise ValueError(f"element must be one of {', '.join(ELEMENTS)}, got {element!r}")
        mesh_cls, elem_cls, order = ELEMENTS[element]
        if not isinstance(mesh, mesh_cls):
            raise TypeError(f"element {element!r} needs a {mesh_cls.__name__}, "
                             f"got a {type(mesh).__name__}")
        self.mesh = mesh
        self.element = element
        self.dim = mesh.dim()
        self.elem = ElementVector(elem_cls())
        self.order = order
        self.basis = Basis(mesh, self.elem, intorder=order)
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

    def gauss_points(self):
        """Coordinates of the Gauss points (n_gp, d) [m]."""
        return self.to_gp(self.basis.mapping.F(self.basis.X))

    def weights(self):
        """Integration weight (volume) of each Gauss point (n_gp,) [m^d]."""
        return self.to_gp(self.basis.dx)

    # ------------------------------------------------------------------ forms
    def strain(self, u):
        """Small strain ``sym grad u`` at the Gauss points (n_gp, d, d)."""
        return self.to_gp(sym_grad(self.basis.interpolate(u)))

    def internal_force(self, sigma):
        """``int sigma : eps(v)`` for stresses (n_gp, d, d) [N]."""
        return asm(_internal, self.basis, sigma=self.from_gp(sigma))

    def stiffness(self, tangent):
        """``int eps(u) : C : eps(v)`` for tangents (n_gp, d, d, d, d) (sparse)."""
        return asm(_stiffness, self.basis, C=self.from_gp(tangent))

    def _facets(self, boundary):
        if boundary not in self.mesh.boundaries:
            raise KeyError(boundary)
        return FacetBasis(self.mesh, self.elem, facets=self.mesh.boundaries[boundary],
                          intorder=self.order)

    def pressure_force(self, boundary, pressure):
        """Nodal forces [N] of a pressure [Pa] (compressive, positive) on a boundary."""
        return asm(_pressure, self._facets(boundary), p=float(pressure))

    def traction_force(self, boundary, traction):
        """Nodal forces [N] of a traction vector (d,) [Pa] on a boundary."""
        fb = self._facets(boundary)
        t = np.asarray(traction, dtype=np.float64)[:, None, None] * np.ones(fb.dx.shape)
        return asm(_vector_load, fb, t=t)

    def body_force(self, density_g):
        """Nodal forces [N] of a body force density (d,) [N/m^3]."""
        b = np.asarray(density_g, dtype=np.float64)[:, None, None]
        return asm(_vector_load, self.basis, t=b * np.ones(self.basis.dx.shape))

    def dofs(self, boundary, component):
        """Degrees of freedom of displacement ``component`` (0..d-1) on a boundary."""
        if boundary not in self.mesh.boundaries:
            raise KeyError(boundary)
        return np.asarray(self.basis.get_dofs(boundary).all(f"u^{component + 1}"))

    def nodal_displacement(self, u):
        """Displacement at the mesh vertices (n_vertices, d) [m]."""
        return u[self.basis.nodal_dofs].T
