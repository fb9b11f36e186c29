"""Rotations from the Rust core: rotation matrices, z-y'-x'' Euler angles and the angle between
two attitudes, for one quaternion or a stack, with clear errors for bad shapes."""

from __future__ import annotations

import numpy as np
import pytest

import orbitflex


def about(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.r_[axis * np.sin(angle / 2), np.cos(angle / 2)]


def product(a, b):
    av, aw, bv, bw = a[:3], a[3], b[:3], b[3]
    return np.r_[aw * bv + bw * av + np.cross(av, bv), aw * bw - av @ bv]


def test_rotation_matrix_is_the_rotation_about_the_axis():
    # Rodrigues' formula for the rotation by 0.7 rad about (1, 2, 2)/3
    k = np.array([1.0, 2.0, 2.0]) / 3.0
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    expected = np.eye(3) + np.sin(0.7) * K + (1 - np.cos(0.7)) * K @ K
    np.testing.assert_allclose(orbitflex.rotation_matrix(about(k, 0.7)), expected, atol=1e-15)
    stack = orbitflex.rotation_matrix(np.stack([about(k, 0.7), [0, 0, 0, 2.0]]))
    assert stack.shape == (2, 3, 3)
    np.testing.assert_allclose(stack[1], np.eye(3), atol=1e-15)  # normalised first


def test_euler_angles_rebuild_the_rotation():
    rng = np.random.default_rng(3)
    quat = rng.normal(size=(20, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    angles = orbitflex.euler_zyx(quat)
    assert angles.shape == (20, 3)
    for q, (yaw, pitch, roll) in zip(quat, angles):
        z, y, x = about([0, 0, 1], yaw), about([0, 1, 0], pitch), about([1, 0, 0], roll)
        np.testing.assert_allclose(orbitflex.rotation_matrix(product(product(z, y), x)),
                                   orbitflex.rotation_matrix(q), atol=1e-14)


def test_rotation_angle_keeps_tiny_angles_and_broadcasts():
    a = about([1, 2, -0.5], 0.7)
    for angle in (1e-12, 1e-9, 1e-3, 2.5):
        b = product(a, about([-0.3, 0.1, 0.9], angle))
        assert orbitflex.rotation_angle(a, b) == pytest.approx(angle, rel=1e-12, abs=1e-15)
        assert orbitflex.rotation_angle(a, -b) == pytest.approx(angle, rel=1e-12, abs=1e-15)
    stack = np.stack([a, about([0, 0, 1], 0.2)])
    np.testing.assert_allclose(orbitflex.rotation_angle(stack, a), [0.0, orbitflex.rotation_angle(a, stack[1])])
    with pytest.raises(orbitflex.ModelError, match=r"q1: expected shape \(4,\) or \(2, 4\)"):
        orbitflex.rotation_angle(stack, np.stack([a, a, a]))
    with pytest.raises(orbitflex.ModelError, match="quat"):
        orbitflex.rotation_matrix([1.0, 0.0, 0.0])
    with pytest.raises(orbitflex.ModelError, match="quat"):
        orbitflex.euler_zyx([np.nan, 0.0, 0.0, 1.0])
