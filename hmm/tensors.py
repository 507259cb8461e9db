"""Small tensor helpers of finite deformation, on stacks of ``(..., d, d)`` matrices.

* :func:`polar` -- ``F = R U``: the rotation and the right stretch;
* :func:`rotation_power` -- ``R^s`` of a rotation (its angle times ``s``, same axis);
* :func:`log_strain` -- Hencky's strain ``ln V = 1/2 ln(F F^T)`` (Eulerian);
* :func:`spatial_tangent` -- the operator ``A`` of the updated-Lagrangian stiffness
  from the Cauchy stress and the micro model's tangent (see its docstring);
* :func:`rotate4` -- ``C'_ijkl = R_ia R_jb R_kc R_ld C_abcd``.

Everything works on one matrix or on a stack; 2D matrices are in-plane (plane strain).
"""

import numpy as np


def polar(f):
    """Rotation ``R`` and right stretch ``U`` of ``F = R U`` (``det F > 0``).

    From the singular value decomposition ``F = W S V^T``: ``R = W V^T``,
    ``U = V S V^T``. A symmetric positive-definite ``F`` gives ``R = I`` to round-off.

    Examples
    --------
    >>> c, s = np.cos(0.3), np.sin(0.3)
    >>> r, u = polar(np.array([[c, -s], [s, c]]) @ np.diag([2.0, 0.5]))
    >>> np.allclose(u, np.diag([2.0, 0.5])), np.allclose(r, [[c, -s], [s, c]])
    (True, True)
    """
    f = np.asarray(f, dtype=np.float64)
    w, s, vt = np.linalg.svd(f)
    r = w @ vt
    u = np.einsum("...ki,...k,...kj->...ij", vt, s, vt)
    return r, u


def rotation_power(r, s):
    """The rotation ``R^s``: the same axis, ``s`` times the angle (one matrix).

    Examples
    --------
    >>> c, n = np.cos(1.0), np.sin(1.0)
    >>> half = rotation_power(np.array([[c, -n], [n, c]]), 0.5)
    >>> bool(np.allclose(half @ half, [[c, -n], [n, c]]))
    True
    """
    r = np.asarray(r, dtype=np.float64)
    d = r.shape[0]
    if d == 2:
        a = s * np.arctan2(r[1, 0] - r[0, 1], r[0, 0] + r[1, 1])
        return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    # axis-angle of R, then Rodrigues' formula for s times the angle
    cos_t = np.clip(0.5 * (np.trace(r) - 1.0), -1.0, 1.0)
    theta = np.arccos(cos_t)
    skew = 0.5 * (r - r.T)
    axis = np.array([skew[2, 1], skew[0, 2], skew[1, 0]])
    n = np.linalg.norm(axis)
    if theta < 1e-12:
        return np.eye(3)
    if n < 1e-8 * theta:  # a half turn: the axis from R + I
        m = r + np.eye(3)
        axis = m[:, np.argmax(np.linalg.norm(m, axis=0))]
        n = np.linalg.norm(axis)
    k = axis / n
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    a = s * theta
    return np.eye(3) + np.sin(a) * kx + (1.0 - np.cos(a)) * (kx @ kx)


def log_strain(f):
    """Hencky's (logarithmic) strain ``ln V = 1/2 ln(F F^T)`` of ``F`` (..., d, d).

    In 2D the in-plane part (the out-of-plane stretch of plane strain is 1).

    Examples
    --------
    >>> np.round(log_strain(np.diag([np.e, 1.0])), 12).tolist()
    [[1.0, 0.0], [0.0, 0.0]]
    """
    f = np.asarray(f, dtype=np.float64)
    b = f @ np.swapaxes(f, -1, -2)
    lam, q = np.linalg.eigh(b)
    return np.einsum("...ik,...k,...jk->...ij", q, 0.5 * np.log(lam), q)


def rotate4(c, r):
    """``C'_ijkl = R_ia R_jb R_kc R_ld C_abcd`` for a tensor (d, d, d, d)."""
    return np.einsum("ia,jb,kc,ld,abcd->ijkl", r, r, r, r, c)


def spatial_tangent(sigma, c):
    """``A`` of the updated-Lagrangian stiffness ``int grad_x v : A : grad_x du dv``.

    ``sigma`` (..., d, d) is the Cauchy stress, ``c`` (..., d, d, d, d) the micro
    model's tangent ``d sigma = c : d eps`` for a symmetric strain increment ``d eps``
    of the current configuration. An objective micro model turns with the material,
    ``d sigma = c : eps + w sigma - sigma w`` for ``g = grad_x du = eps + w``; the
    change of the integrand ``sigma : grad_x v J`` with the configuration adds
    ``sigma tr g - sigma g^T``. Together::

        A_ijkl = c_ijkl + sigma_ij d_kl
                 + 1/2 (d_ik sigma_lj - d_il sigma_kj - sigma_ik d_jl - sigma_il d_jk)

    (the geometric, or initial-stress, part is everything but ``c``). ``A`` has no
    major symmetry in general: the Newton matrix is not symmetric.

    Examples
    --------
    >>> c = np.ones((2, 2, 2, 2))
    >>> bool(np.array_equal(spatial_tangent(np.zeros((2, 2)), c), c))  # unstressed
    True
    """
    sigma = np.asarray(sigma, dtype=np.float64)
    d = sigma.shape[-1]
    e = np.eye(d)
    geo = (np.einsum("...ij,kl->...ijkl", sigma, e)
           + 0.5 * (np.einsum("ik,...lj->...ijkl", e, sigma)
                    - np.einsum("il,...kj->...ijkl", e, sigma)
                    - np.einsum("...ik,jl->...ijkl", sigma, e)
                    - np.einsum("...il,jk->...ijkl", sigma, e)))
    return np.asarray(c, dtype=np.float64) + geo
