"""The neck's fade of the head turn: where it runs, and the joint blend both decoders share."""

import numpy as np
import pytest

from mpeg4.fat import rotation_matrix
from mpeg4.generic_head import load_generic_head
from mpeg4.neck import (NECK_SEGMENTS, RIGID_PREFIXES, blend_turn, joint_weights, matrix_from_quat, neck_cut,
                        neck_fade, quat_from_matrix, quat_power)


@pytest.fixture(scope="module")
def head():
    return load_generic_head()


def test_the_fade_runs_from_the_cut_to_the_chin(head):
    nf = neck_fade(head)
    cut = neck_cut(head.skin)
    s, v = nf.fade["skin"], head.skin.vertices
    assert len(cut) > 20 and np.all(s[cut] == 0.0)
    assert s.min() >= 0.0 and s.max() <= 1.0
    up = (nf.pivot - nf.base) / np.linalg.norm(nf.pivot - nf.base)
    above_chin = (v - nf.base) @ up >= (head.fp_position("2.1") - nf.base) @ up
    assert np.all(s[above_chin] == 1.0)  # the face, the skull, the jaw
    assert 0.02 < np.mean(s < 1) < 0.2  # the neck only
    for name, p in head.parts.items():
        if name.startswith(RIGID_PREFIXES):
            assert np.all(nf.fade[name] == 1.0), name
    # Up the neck the fade only grows: along each azimuth, sorted by height.
    d = v - nf.base
    side = np.cross(up, [0.0, 0.0, 1.0])
    phi = np.arctan2(d @ side, d @ np.cross(side, up))
    h = d @ up
    for lo in np.linspace(-np.pi, np.pi, 24, endpoint=False):
        sel = np.flatnonzero((phi >= lo) & (phi < lo + np.pi / 48) & (s > 0) & (s < 1))
        order = sel[np.argsort(h[sel])]
        assert np.all(np.diff(s[order]) >= -0.05), lo  # a bin is 3.75° wide: the cut's slope inside it


def test_a_head_without_a_neck_turns_rigidly(head):
    no_chin = head.copy()
    no_chin.feature_points = {k: b for k, b in head.feature_points.items() if k != "2.1"}
    assert all(np.all(s == 1.0) for s in neck_fade(no_chin).fade.values())


def test_joint_blend():
    s = np.linspace(0, 1, 101)
    w = joint_weights(s)
    assert w.shape == (101, NECK_SEGMENTS + 1)
    np.testing.assert_allclose(w.sum(axis=1), 1.0)
    assert np.all((w > 0).sum(axis=1) <= 2)
    np.testing.assert_allclose(w @ np.arange(NECK_SEGMENTS + 1) / NECK_SEGMENTS, s)  # the share is the fade
    axis = np.array([0.3, 1.0, -0.2]) / np.linalg.norm([0.3, 1.0, -0.2])
    a = rotation_matrix(axis, np.radians(70))
    q = quat_from_matrix(a)
    np.testing.assert_allclose(matrix_from_quat(q), a, atol=1e-12)
    np.testing.assert_allclose(matrix_from_quat(quat_power(q, 0.25)), rotation_matrix(axis, np.radians(17.5)),
                               atol=1e-12)
    pivot = np.array([0.0, -0.02, -0.01])
    rng = np.random.default_rng(1)
    v = rng.normal(0, 0.1, (50, 3))
    b = pivot - a @ pivot
    np.testing.assert_allclose(blend_turn(v, joint_weights(np.ones(50)), a, b, pivot), v @ a.T + b, atol=1e-15)
    np.testing.assert_allclose(blend_turn(v, joint_weights(np.zeros(50)), a, b, pivot), v, atol=1e-15)
    # At a joint's share the blend is the exact partial turn (a slerp).
    half = rotation_matrix(axis, np.radians(35))
    np.testing.assert_allclose(blend_turn(v, joint_weights(np.full(50, 0.5)), a, b, pivot),
                               (v - pivot) @ half.T + pivot, atol=1e-12)
