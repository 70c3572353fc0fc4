"""Homogeneous transforms: explicit forms, orthonormality, vectorisation."""

from __future__ import annotations

import numpy as np
import pytest

from twin.errormodel import transforms as tf


def test_translation_moves_a_point() -> None:
    p = tf.translation(1.0, -2.0, 3.0) @ np.array([0.5, 0.5, 0.5, 1.0])
    np.testing.assert_array_equal(p, [1.5, -1.5, 3.5, 1.0])


@pytest.mark.parametrize(
    ("rot", "src", "dst"),
    [
        (tf.rotation_x, [0, 1, 0], [0, 0, 1]),  # right-handed: Y turns to Z about X
        (tf.rotation_y, [0, 0, 1], [1, 0, 0]),  # Z turns to X about Y
        (tf.rotation_z, [1, 0, 0], [0, 1, 0]),  # X turns to Y about Z
    ],
)
def test_rotations_are_right_handed(rot, src, dst) -> None:
    v = rot(np.pi / 2) @ np.array([*src, 0.0])
    np.testing.assert_allclose(v[:3], dst, atol=1e-15)


@pytest.mark.parametrize("rot", [tf.rotation_x, tf.rotation_y, tf.rotation_z])
def test_rotations_are_proper_and_vectorised(rot) -> None:
    angles = np.random.default_rng(1).uniform(-np.pi, np.pi, 50)
    stack = rot(angles)
    assert stack.shape == (50, 4, 4)
    r = stack[:, :3, :3]
    np.testing.assert_allclose(r @ r.transpose(0, 2, 1), np.broadcast_to(np.eye(3), (50, 3, 3)), atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-14)
    for i in (0, 17, 49):
        np.testing.assert_array_equal(stack[i], rot(angles[i]))


def test_small_error_matrix_explicit_form() -> None:
    dx, dy, dz, ex, ey, ez = 1.0, 2.0, 3.0, 0.1, 0.2, 0.3
    expected = [[1, -ez, ey, dx], [ez, 1, -ex, dy], [-ey, ex, 1, dz], [0, 0, 0, 1]]
    np.testing.assert_array_equal(tf.small_error_matrix(dx, dy, dz, ex, ey, ez), expected)


def test_zero_errors_give_identity_exactly() -> None:
    np.testing.assert_array_equal(tf.small_error_matrix(), np.eye(4))
    np.testing.assert_array_equal(tf.exact_error_matrix(), np.eye(4))
    np.testing.assert_array_equal(tf.small_error_matrix(dz=np.zeros(3)), tf.identity(3))


def test_exact_error_matrix_is_translation_times_rz_ry_rx() -> None:
    a, b, c = 0.3, -0.2, 0.7
    expected = tf.translation(1, 2, 3) @ tf.rotation_z(c) @ tf.rotation_y(b) @ tf.rotation_x(a)
    np.testing.assert_allclose(tf.exact_error_matrix(1, 2, 3, a, b, c), expected, atol=1e-15)


def test_exact_and_small_agree_to_first_order() -> None:
    rng = np.random.default_rng(2)
    x = rng.uniform(-1, 1, 6)
    diffs = [
        np.abs(tf.exact_error_matrix(*(eps * x)) - tf.small_error_matrix(*(eps * x))).max()
        for eps in (1e-2, 5e-3)
    ]
    assert diffs[0] < 1e-3
    assert 3.5 < diffs[0] / diffs[1] < 4.5  # the difference is second order


def test_vectorised_error_matrices_broadcast_scalars_and_arrays() -> None:
    dz = np.linspace(-1e-3, 1e-3, 7)
    for build in (tf.small_error_matrix, tf.exact_error_matrix):
        stack = build(dx=1e-4, dz=dz, ey=2e-4)
        assert stack.shape == (7, 4, 4)
        for i in range(7):
            np.testing.assert_array_equal(stack[i], build(dx=1e-4, dz=dz[i], ey=2e-4))


def test_generators_sum_to_small_error_matrix() -> None:
    x = np.array([1.0, -2.0, 3.0, 0.4, -0.5, 0.6])
    np.testing.assert_allclose(
        np.eye(4) + np.einsum("q,qij->ij", x, tf.error_generators()), tf.small_error_matrix(*x)
    )


def test_apply_constant_and_stacked() -> None:
    rng = np.random.default_rng(3)
    m = tf.rotation_y(rng.uniform(size=5)) @ tf.translation(1, 2, 3)
    v = np.c_[rng.uniform(size=(5, 3)), np.ones(5)]
    np.testing.assert_allclose(tf.apply(m, v), np.stack([m[i] @ v[i] for i in range(5)]))
    np.testing.assert_allclose(tf.apply(m[0], v), np.stack([m[0] @ v[i] for i in range(5)]))
