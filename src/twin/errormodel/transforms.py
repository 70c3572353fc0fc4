"""4x4 homogeneous transforms of the multi-body error model.

Conventions: column vectors, ``p_base = M @ p_body``; rotations are active and right-handed
(``rotation_z(a)`` turns +X towards +Y). Lengths in metres, angles in radians.

Every builder broadcasts its arguments: scalars give one ``(4, 4)`` matrix, arrays of shape ``S``
give a stack of shape ``S + (4, 4)``. The model is evaluated on time series of 1e4..1e6 samples, so
nothing here loops over samples in Python.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "ERROR_PARAMETERS",
    "apply",
    "error_generators",
    "error_matrix",
    "exact_error_matrix",
    "identity",
    "rotation_x",
    "rotation_y",
    "rotation_z",
    "small_error_matrix",
    "translation",
]

#: The six error parameters of one error characteristic matrix, in this order everywhere:
#: three translations along X, Y, Z and three small rotations about X, Y, Z (A, B, C axes).
ERROR_PARAMETERS: tuple[str, ...] = ("dx", "dy", "dz", "ex", "ey", "ez")

Matrix = NDArray[np.float64]


def _stack(*args: ArrayLike) -> tuple[list[NDArray[np.float64]], Matrix]:
    """Broadcast the arguments and return them with an identity stack of their common shape."""
    arrays = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in args))
    shape = arrays[0].shape
    out = np.zeros((*shape, 4, 4))
    out[..., [0, 1, 2, 3], [0, 1, 2, 3]] = 1.0
    return list(arrays), out


def identity(n: int | None = None) -> Matrix:
    """The 4x4 identity, or a stack of ``n`` of them."""
    if n is None:
        return np.eye(4)
    return np.broadcast_to(np.eye(4), (n, 4, 4)).copy()


def translation(x: ArrayLike = 0.0, y: ArrayLike = 0.0, z: ArrayLike = 0.0) -> Matrix:
    """Pure translation by ``(x, y, z)``."""
    (x, y, z), m = _stack(x, y, z)
    m[..., 0, 3] = x
    m[..., 1, 3] = y
    m[..., 2, 3] = z
    return m


def _rotation(angle: ArrayLike, i: int, j: int) -> Matrix:
    # Rotation in the (i, j) plane turning axis i towards axis j; the remaining axis is fixed.
    (a,), m = _stack(angle)
    c, s = np.cos(a), np.sin(a)
    m[..., i, i] = c
    m[..., j, j] = c
    m[..., i, j] = -s
    m[..., j, i] = s
    return m


def rotation_x(angle: ArrayLike) -> Matrix:
    """Rotation about X (the A axis) by ``angle`` radians."""
    return _rotation(angle, 1, 2)


def rotation_y(angle: ArrayLike) -> Matrix:
    """Rotation about Y (the B axis, the spindle axis of the tester) by ``angle`` radians."""
    return _rotation(angle, 2, 0)


def rotation_z(angle: ArrayLike) -> Matrix:
    """Rotation about Z (the C axis) by ``angle`` radians."""
    return _rotation(angle, 0, 1)


def error_matrix(params: Sequence[ArrayLike], *, exact: bool = False) -> Matrix:
    """An error characteristic matrix (the paper's dT_ijp or dT_ijs) from its six parameters
    ``(dx, dy, dz, ex, ey, ez)`` (:data:`ERROR_PARAMETERS`).

    ``exact=False``, the paper's first-order matrix (small-angle rotation, as in the MBS
    literature): ``[[1, -ez, ey, dx], [ez, 1, -ex, dy], [-ey, ex, 1, dz], [0, 0, 0, 1]]``. Exactly
    ``I`` when all six parameters are zero; linear in them, so ``error_matrix(...) - I`` is the
    sum of ``parameter * generator`` (see :func:`error_generators`).

    ``exact=True``, a full rotation: ``translation(dx, dy, dz) @ Rz(ez) @ Ry(ey) @ Rx(ex)``. It
    agrees with the first-order matrix to first order; use it to check how much the dropped
    higher-order terms matter.
    """
    (dx, dy, dz, ex, ey, ez), m = _stack(*params)
    (_exact_rotation if exact else _small_rotation)(m, ex, ey, ez)
    m[..., 0, 3] = dx
    m[..., 1, 3] = dy
    m[..., 2, 3] = dz
    return m


def _small_rotation(m: Matrix, ex: Matrix, ey: Matrix, ez: Matrix) -> None:
    """Fill the rotation block of the identity stack ``m`` with I + [e]x (first order)."""
    m[..., 0, 1] = -ez
    m[..., 0, 2] = ey
    m[..., 1, 0] = ez
    m[..., 1, 2] = -ex
    m[..., 2, 0] = -ey
    m[..., 2, 1] = ex


def _exact_rotation(m: Matrix, ex: Matrix, ey: Matrix, ez: Matrix) -> None:
    """Fill the rotation block of ``m`` with Rz(ez) @ Ry(ey) @ Rx(ex), written out so a stack
    of 1e6 matrices costs a few array operations."""
    ca, sa = np.cos(ex), np.sin(ex)
    cb, sb = np.cos(ey), np.sin(ey)
    cc, sc = np.cos(ez), np.sin(ez)
    m[..., 0, 0] = cc * cb
    m[..., 0, 1] = cc * sb * sa - sc * ca
    m[..., 0, 2] = cc * sb * ca + sc * sa
    m[..., 1, 0] = sc * cb
    m[..., 1, 1] = sc * sb * sa + cc * ca
    m[..., 1, 2] = sc * sb * ca - cc * sa
    m[..., 2, 0] = -sb
    m[..., 2, 1] = cb * sa
    m[..., 2, 2] = cb * ca


def _six(params: Sequence[ArrayLike], named: Mapping[str, ArrayLike]) -> list[ArrayLike]:
    """The six parameters given by position and by name (:data:`ERROR_PARAMETERS`), 0 for the rest."""
    six: list[ArrayLike] = [*params, *[0.0] * (6 - len(params))]
    for name, value in named.items():
        six[ERROR_PARAMETERS.index(name)] = value
    return six


def small_error_matrix(*params: ArrayLike, **named: ArrayLike) -> Matrix:
    """The first-order error matrix (:func:`error_matrix` with ``exact=False``) of the six
    parameters by position or by name (``dz=...``)."""
    return error_matrix(_six(params, named))


def exact_error_matrix(*params: ArrayLike, **named: ArrayLike) -> Matrix:
    """The error matrix with a full rotation (:func:`error_matrix` with ``exact=True``)."""
    return error_matrix(_six(params, named), exact=True)


def error_generators() -> Matrix:
    """The six 4x4 generators ``G_q`` with ``error_matrix(x) = I + sum_q x_q G_q``.

    Shape ``(6, 4, 4)``, ordered as :data:`ERROR_PARAMETERS`.
    """
    g = np.zeros((6, 4, 4))
    for q in range(6):
        x = np.zeros(6)
        x[q] = 1.0
        g[q] = error_matrix(x) - np.eye(4)
    return g


def apply(m: Matrix, v: NDArray[np.float64]) -> NDArray[np.float64]:
    """``m @ v`` for a matrix or a stack of matrices and one vector or a stack of vectors.

    ``m``: ``(4, 4)`` or ``(N, 4, 4)``; ``v``: ``(4,)`` or ``(N, 4)``. A constant matrix goes through
    one BLAS call on the whole stack instead of a per-sample matmul.
    """
    if m.ndim == 2:
        return v @ m.T
    return np.einsum("...ij,...j->...i", m, v)
