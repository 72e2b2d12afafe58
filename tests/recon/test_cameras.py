"""Cameras recovered from 3D feature points and their pixels."""

import numpy as np
import pytest

from mpeg4 import InputError
from mpeg4.camera import Camera, look_rotation
from recon.texture.cameras import fit_camera


def _points(n=40, seed=0):
    rng = np.random.default_rng(seed)
    return {f"p{k}": p for k, p in enumerate(rng.uniform(-0.1, 0.1, (n, 3)))}


def _project(cam, pts):
    return {k: cam.project(p[None])[0] for k, p in pts.items()}


@pytest.mark.parametrize("yaw,focal", [(0.0, None), (90.0, None), (8.0, 4000.0), (-85.0, 3000.0)])
def test_fit_camera_recovers_the_camera_exactly(yaw, focal):
    pts = _points()
    rot = look_rotation(yaw, 5.0)
    centre = rot[2] * 1.5 + [0.01, -0.02, 0.03]
    truth = Camera(900, 1100, rot, centre, focal_px=focal, scale_px=None if focal else 3100.0,
                   principal=None if focal else (440.0, 560.0))
    fitted = fit_camera(pts, _project(truth, pts), 900, 1100, focal_px=focal)
    assert fitted.rms_px < 1e-6
    probe = np.random.default_rng(1).uniform(-0.15, 0.15, (100, 3))
    np.testing.assert_allclose(fitted.project(probe), truth.project(probe), atol=1e-5)
    # The flipped photo's camera: a point lands where its mirror image was, flipped.
    flip = fitted.flipped()
    mirrored = probe * [-1, 1, 1]
    expect = truth.project(mirrored)
    np.testing.assert_allclose(flip.project(probe), np.c_[899 - expect[:, 0], expect[:, 1]], atol=1e-5)


def test_fit_camera_refuses_too_few_or_flat_points():
    pts = _points(3)
    cam = Camera(100, 100, np.eye(3), [0, 0, 2.0], scale_px=100.0)
    with pytest.raises(InputError, match="needs 4"):
        fit_camera(pts, _project(cam, pts), 100, 100)
    flat = {f"q{k}": np.array([x, y, 0.0]) for k, (x, y) in enumerate(np.random.default_rng(2).random((8, 2)))}
    with pytest.raises(InputError, match="plane"):
        fit_camera(flat, _project(cam, flat), 100, 100)
