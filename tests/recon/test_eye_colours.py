"""The eyes' colours from the photo: the white between the iris and the corners, not a
fixed paper white; none where lowered lids hide it."""

import numpy as np

from recon.texture.materials import SCLERA_RGB, eye_texture, sclera_colour

SKIN, WHITE, IRIS = (150, 100, 80), (205, 196, 190), (70, 55, 40)


def _eye(lid_open: float = 1.0) -> tuple[np.ndarray, np.ndarray, list]:
    """(H, W, 3) photo of one eye on skin: an almond opening between the corners, the
    iris (radius 12 px) in its middle, dark lashes on the upper margin; ``lid_open`` the
    opening's half-height over 14 px."""
    h, w = 80, 160
    img = np.empty((h, w, 3), np.uint8)
    img[:] = SKIN
    yy, xx = np.mgrid[:h, :w]
    pupil = np.array([80.0, 40.0])
    corners = [np.array([30.0, 42.0]), np.array([130.0, 42.0])]
    half = 14.0 * lid_open * np.clip(1 - ((xx - 80) / 50.0) ** 2, 0, None)
    opening = np.abs(yy - 41) < half
    img[opening] = WHITE
    img[opening & (np.hypot(xx - pupil[0], yy - pupil[1]) < 12)] = IRIS
    img[opening & (np.hypot(xx - pupil[0], yy - pupil[1]) < 4)] = (10, 10, 10)
    lashes = np.abs(yy - (41 - half)) < 1.5
    img[lashes & (half > 0)] = (30, 25, 20)
    return img, pupil, corners


def test_the_white_is_read_between_the_iris_and_the_corners():
    img, pupil, corners = _eye()
    white = sclera_colour(img, pupil, corners, 12.0)
    assert white is not None
    np.testing.assert_allclose(white, WHITE, atol=6)


def test_lowered_lids_show_no_white():
    """Lids down to a slit narrower than the samples' band: the pixels are skin and lashes,
    too coloured for a white."""
    img, pupil, corners = _eye(lid_open=0.08)
    assert sclera_colour(img, pupil, corners, 12.0) is None


def test_the_texture_takes_the_white_given():
    tex = eye_texture(64, IRIS, WHITE)
    assert tuple(tex[1, 1]) == WHITE  # a corner: the eye's back
    assert tuple(eye_texture(64, IRIS)[1, 1]) == SCLERA_RGB
