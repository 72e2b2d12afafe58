"""DFFD of a head: exact at the controls, exact for affine motion, rigid parts stay rigid."""

import numpy as np
import pytest
import trimesh

from mpeg4 import FP_IDS, FeaturePointBinding, Head, InputError, Part
from recon.shape.deform import bounding_controls, deform_head, dffd, fit_similarity, rbf_deform
from recon.shape.sibson import NaturalNeighbours


@pytest.fixture(scope="module")
def head():
    skin = trimesh.creation.icosphere(subdivisions=3, radius=0.1)
    eye = trimesh.creation.icosphere(subdivisions=1, radius=0.012)
    centre = np.array([0.03, 0.02, 0.08])
    rng = np.random.default_rng(0)
    fp_vertices = rng.choice(len(skin.vertices), 24, replace=False)
    fps = {i: FeaturePointBinding.at_vertex("skin", v) for i, v in zip(FP_IDS, fp_vertices)}
    fps["3.5"] = FeaturePointBinding.at_vertex("eye_l", 0)
    parts = [Part("skin", skin.vertices, skin.faces), Part("eye_l", eye.vertices + centre, eye.faces, centre=centre)]
    return Head(parts, fps)


def _targets(head, f):
    return {i: f(head.fp_position(i)[None])[0] for i in head.feature_points}


def test_feature_point_vertices_land_exactly_on_their_targets(head):
    rng = np.random.default_rng(1)
    goal = {i: p + rng.normal(0, 0.004, 3) for i, p in head.fp_positions().items() if i != "3.5"}
    out = deform_head(head, goal)
    err = max(np.linalg.norm(out.fp_position(i) - g) for i, g in goal.items())
    assert err < 1e-9
    # Vertices far from every feature point still moved smoothly (no vertex left behind).
    assert np.isfinite(out.skin.vertices).all()


@pytest.mark.parametrize("method", ["dffd", "rbf"])
def test_affine_motion_is_reproduced_exactly(head, method):
    a = np.array([[1.1, 0.05, 0.0], [-0.02, 0.95, 0.03], [0.01, 0.0, 1.05]])
    t = np.array([0.01, -0.02, 0.005])
    out = deform_head(head, _targets(head, lambda p: p @ a.T + t), method=method, far_field="affine")
    np.testing.assert_allclose(out.skin.vertices, head.skin.vertices @ a.T + t, atol=1e-9)


def test_rigid_parts_keep_their_shape(head):
    rng = np.random.default_rng(2)
    goal = {i: p + rng.normal(0, 0.005, 3) for i, p in head.fp_positions().items()}
    out = deform_head(head, goal)
    before, after = head.parts["eye_l"].vertices, out.parts["eye_l"].vertices
    d0 = np.linalg.norm(before[:, None] - before[None], axis=2)
    d1 = np.linalg.norm(after[:, None] - after[None], axis=2)
    ratio = d1[d0 > 0] / d0[d0 > 0]
    assert ratio.max() - ratio.min() < 1e-9  # one uniform scale
    # The centre moves with the eyeball.
    np.testing.assert_allclose(after.mean(axis=0) - out.parts["eye_l"].centre,
                               (before.mean(axis=0) - head.parts["eye_l"].centre) * ratio[0], atol=1e-9)


def test_dffd_is_smooth_where_rbf_is_exact_too():
    rng = np.random.default_rng(3)
    controls = np.vstack([bounding_controls(rng.random((50, 3))), rng.random((30, 3))])
    displaced = controls + rng.normal(0, 0.01, controls.shape)
    for f in (dffd, rbf_deform):
        np.testing.assert_allclose(f(controls, controls, displaced), displaced, atol=1e-9)


def test_bounding_controls_enclose_the_points_and_are_unique():
    pts = np.random.default_rng(4).random((200, 3))
    box = bounding_controls(pts)
    assert len(np.unique(box.round(12), axis=0)) == 27
    NaturalNeighbours(np.vstack([box, pts[:10]])).coordinates(pts)  # all inside the hull


def test_fit_similarity_recovers_a_known_transform():
    rng = np.random.default_rng(5)
    p = rng.random((10, 3))
    q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    q *= np.sign(np.linalg.det(q))
    s = fit_similarity(p, 1.3 * p @ q.T + [1, 2, 3])
    np.testing.assert_allclose(s.rotation, q, atol=1e-12)
    assert abs(s.scale - 1.3) < 1e-12


def test_bad_input(head):
    with pytest.raises(InputError, match="unknown deformation method"):
        deform_head(head, head.fp_positions(), method="nearest")
    with pytest.raises(InputError, match="12.1"):
        deform_head(head, {"12.1": np.zeros(3)})
    with pytest.raises(InputError, match="at least 4"):
        deform_head(head, dict(list(head.fp_positions().items())[:3]))
