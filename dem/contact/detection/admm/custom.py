"""The ADMM kernel for a user's SDF (:func:`make_admm`).

The solver reaches a CUSTOM row's SDF through ``fn``, the address of a C wrapper of the
user's function (:func:`dem._jit.sdf_address`), so :func:`.solver.admm_contact_fn` is
compiled (and cached) once for all of them; :func:`make_admm` binds one address into a
kernel with :func:`admm_contact`'s signature, for the time loops.
"""

from ...._jit import kernel, sdf_address
from .solver import admm_contact, admm_contact_fn

_CUSTOM = {}


def make_admm(custom_sdf=None):
    """The :func:`admm_contact` kernel with CUSTOM rows evaluated by ``custom_sdf``.

    Parameters
    ----------
    custom_sdf : numba dispatcher or None
        A ``@numba.njit`` function ``custom_sdf(x, y, z, p) -> float``: the signed
        distance [m] of the point (x, y, z) of the user's frame, with ``p`` the row's
        four parameters (:attr:`ShapeTable.param`, a (4,) float64 array). It must be
        an exact distance outside the shape. ``None`` gives the built-in kernel.

    Returns
    -------
    The compiled kernel, with :func:`admm_contact`'s signature (memoised per function).
    The solver is compiled (and cached) once for every custom SDF: the user's function
    reaches it as the address of a ``cfunc`` wrapping it.
    """
    if custom_sdf is None:
        return admm_contact
    if custom_sdf not in _CUSTOM:
        address = sdf_address(custom_sdf)

        @kernel(cache=False)  # it holds this process's address of the user's function
        def admm_contact_custom(dim, ka, sa, a, kb, sb, b, sx, sy, sz, pos, rot, normal,
                                geo, warm, k, tol, max_iter):
            return admm_contact_fn(address, dim, ka, sa, a, kb, sb, b, sx, sy, sz, pos,
                                   rot, normal, geo, warm, k, tol, max_iter)

        _CUSTOM[custom_sdf] = admm_contact_custom
    return _CUSTOM[custom_sdf]


def custom_address(custom_sdf):
    """The address of ``custom_sdf``'s C wrapper: the ``fn`` argument of the ``*_fn``
    kernels (:func:`admm_contact_fn`,
    :func:`dem.contact.detection.nodes.nodes_contact_fn`). Wraps it once, as
    :func:`make_admm` does."""
    return sdf_address(custom_sdf)
