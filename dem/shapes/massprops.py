"""Exact mass properties of polygons and polyhedra, and principal axes of inertia.

The integrals come from the divergence theorem, written as sums over simplices with one
corner at the origin: triangles ``(0, p_e, p_e+1)`` of the polygon's edges in 2D,
tetrahedra ``(0, a, b, c)`` of the outward boundary triangles in 3D. Each simplex ``T``
of signed measure ``|T|`` with corners ``p_0 = 0, p_1 .. p_d`` contributes

* ``|T|`` to the measure (area in 2D, volume in 3D),
* ``|T| S / (d + 1)`` to the first moment, with ``S = p_1 + ... + p_d``,
* ``|T| (sum_k p_k p_k^T + S S^T) / ((d + 1)(d + 2))`` to the second moment
  ``C = int x x^T dV``,

which is exact for linear and quadratic integrands over a simplex. The inertia tensor
about the centroid ``c`` of a body of density ``rho`` and volume ``V`` is
``I = rho (tr(C_c) 1 - C_c)`` with ``C_c = C - V c c^T``; in 2D (a prism of unit
thickness, 1 m) the polar moment is ``rho tr(C_c)``.
"""

import numpy as np


def simplex_moments(vertices, simplices):
    """Measure, first and second moments of a closed, outward-oriented boundary.

    Parameters
    ----------
    vertices : ndarray, shape (k, d), float64
        Boundary vertices [m], ``d`` = 2 or 3.
    simplices : ndarray, shape (t, d), int
        Boundary facets as vertex indices: edges ``(i, j)`` counter-clockwise in 2D,
        triangles counter-clockwise seen from outside in 3D.

    Returns
    -------
    measure : float
        Area [m^2] in 2D, volume [m^3] in 3D (negative if the boundary is inward).
    first : ndarray, shape (d,)
        ``int x dV`` [m^3] in 2D, [m^4] in 3D.
    second : ndarray, shape (d, d)
        ``int x x^T dV`` about the origin [m^4] in 2D, [m^5] in 3D.

    Examples
    --------
    >>> v = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> edges = np.array([[0, 1], [1, 2], [2, 3], [3, 0]])
    >>> area, first, second = simplex_moments(v, edges)
    >>> float(area), first.tolist(), round(float(second[0, 0]), 12)
    (1.0, [0.5, 0.5], 0.333333333333)
    """
    v = np.asarray(vertices, dtype=np.float64)
    corners = v[np.asarray(simplices)]  # (t, d, d): corner k of simplex t
    d = v.shape[1]
    size = np.linalg.det(corners) / (2.0 if d == 2 else 6.0)  # signed |T|
    s = corners.sum(axis=1)  # (t, d)
    measure = float(size.sum())
    first = (size[:, None] * s).sum(axis=0) / (d + 1)
    outer = np.einsum("tki,tkj->tij", corners, corners) + np.einsum("ti,tj->tij", s, s)
    second = np.einsum("t,tij->ij", size, outer) / ((d + 1) * (d + 2))
    return measure, first, second


def inertia_from_moments(measure, first, second, density):
    """Mass, centroid and inertia about the centroid from the raw moments.

    Parameters
    ----------
    measure : float
        Area [m^2] (2D) or volume [m^3] (3D), > 0.
    first : ndarray, shape (d,)
        ``int x dV`` about the origin.
    second : ndarray, shape (d, d)
        ``int x x^T dV`` about the origin.
    density : float
        Mass density [kg/m^3]; in 2D per metre of thickness.

    Returns
    -------
    mass : float
        [kg].
    centroid : ndarray, shape (d,)
        [m].
    inertia : float or ndarray, shape (3, 3)
        Polar moment [kg m^2] about the centroid in 2D, inertia tensor [kg m^2] in 3D.
    """
    centroid = np.asarray(first, dtype=np.float64) / measure
    central = np.asarray(second, dtype=np.float64)
    central = central - measure * np.outer(centroid, centroid)
    central = 0.5 * (central + central.T)
    if centroid.shape[0] == 2:
        return density * measure, centroid, float(density * np.trace(central))
    inertia = density * (np.trace(central) * np.eye(3) - central)
    return density * measure, centroid, inertia


def boundary_mass_properties(vertices, simplices, density):
    """Exact mass, centroid and inertia of a solid from its outward boundary.

    The moments are taken about the mean vertex and moved to the frame's origin after,
    so a small shape far from the origin keeps its precision.

    Parameters
    ----------
    vertices : ndarray, shape (k, d), float64
        Boundary vertices [m], ``d`` = 2 or 3.
    simplices : ndarray, shape (t, d), int
        Outward boundary facets (see :func:`simplex_moments`).
    density : float
        Mass density [kg/m^3]; in 2D per metre of thickness.

    Returns
    -------
    mass, centroid, inertia
        As :func:`inertia_from_moments`; ``mass / density`` is the area or volume.
    """
    v = np.asarray(vertices, dtype=np.float64)
    ref = v.mean(axis=0)
    mass, centroid, inertia = inertia_from_moments(*simplex_moments(v - ref, simplices),
                                                   density)
    return mass, centroid + ref, inertia


def check_density(density):
    """Return ``density`` [kg/m^3] as a float; ValueError unless > 0 and finite."""
    rho = float(density)
    if not (rho > 0.0 and np.isfinite(rho)):
        raise ValueError(
            f"density must be a positive finite number [kg/m^3], got {density}")
    return rho


def check_scale(s):
    """Return the scale factor ``s`` as a float; ValueError unless > 0 and finite."""
    factor = float(s)
    if not (factor > 0.0 and np.isfinite(factor)):
        raise ValueError(f"scale factor must be a positive finite number, got {s}")
    return factor


def principal_axes(inertia):
    """Principal moments and axes of a symmetric inertia tensor.

    Parameters
    ----------
    inertia : ndarray, shape (3, 3)
        Inertia tensor [kg m^2] about the centroid.

    Returns
    -------
    moments : ndarray, shape (3,)
        Principal moments [kg m^2], ascending.
    rotation : ndarray, shape (3, 3)
        Proper rotation (det +1) whose columns are the principal axes, so that
        ``rotation.T @ inertia @ rotation`` is ``diag(moments)``.

    Examples
    --------
    >>> moments, rot = principal_axes(np.diag([3.0, 1.0, 2.0]))
    >>> moments.tolist(), round(float(np.linalg.det(rot)), 12)
    ([1.0, 2.0, 3.0], 1.0)
    """
    tensor = np.asarray(inertia, dtype=np.float64)
    moments, rotation = np.linalg.eigh(0.5 * (tensor + tensor.T))
    if np.linalg.det(rotation) < 0.0:
        rotation[:, 2] = -rotation[:, 2]
    return moments, rotation


def moments_about_axes(inertia):
    """Principal moments [kg m^2] (3,) in the order of the frame's axes when it can.

    If ``inertia`` (3, 3) is diagonal (products of inertia below 1e-12 of the largest
    moment: the frame is principal) its diagonal is returned, in x, y, z order, so it
    matches a body frame; otherwise the eigenvalues, ascending, which is the order of
    the axes that :func:`principal_axes` gives.

    Examples
    --------
    >>> moments_about_axes(np.diag([3.0, 1.0, 2.0])).tolist()
    [3.0, 1.0, 2.0]
    """
    tensor = np.asarray(inertia, dtype=np.float64)
    diag = np.diag(tensor).copy()
    if np.abs(tensor - np.diag(diag)).max() <= 1e-12 * np.abs(diag).max():
        return diag
    return principal_axes(tensor)[0]


def check_body_frame(centroid, inertia, size, what):
    """Raise ValueError unless the centroid is at the origin and the axes are principal.

    Parameters
    ----------
    centroid : ndarray, shape (d,)
        Centroid [m] in the shape's frame.
    inertia : float or ndarray, shape (3, 3)
        Polar moment (2D, not checked) or inertia tensor (3D) [kg m^2].
    size : float
        Length scale [m] of the shape (its bounding radius).
    what : str
        Name of the shape, for the error message.
    """
    offset = float(np.linalg.norm(centroid))
    if offset > 1e-12 * size:
        raise ValueError(
            f"{what} is not in its body frame: centroid is offset by {offset:.3e} m "
            f"(size {size:.3e} m) from the origin; call principal() first")
    if np.ndim(inertia) == 2:
        off = np.abs(inertia - np.diag(np.diag(inertia))).max()
        scale = np.abs(np.diag(inertia)).max()
        if off > 1e-12 * scale:
            raise ValueError(
                f"{what} is not in its body frame: products of inertia up to {off:.3e} "
                f"kg m^2 (moments up to {scale:.3e}); call principal() first")
