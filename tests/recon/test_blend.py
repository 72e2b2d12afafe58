"""The band-by-band multiresolution spline gives OpenCV's multi-band blender's bytes."""

import numpy as np
import pytest

from recon.texture.blend import blend_multiband


def _layers(h, w, seed):
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[:h, :w]
    # Smooth gradients with noise on top, as photos are, and one layer of pure noise.
    smooth = [np.clip(np.stack([(xx * 255 // w + 40 * k), (yy * 255 // h), np.full((h, w), 60 * k)], axis=-1)
                      + rng.integers(-12, 12, (h, w, 3)), 0, 255).astype(np.uint8) for k in range(2)]
    return smooth + [rng.integers(0, 256, (h, w, 3)).astype(np.uint8)]


@pytest.mark.parametrize("h,w,levels", [(256, 256, 3), (200, 300, 4), (97, 131, 2), (64, 48, None), (40, 40, 7)])
def test_opencv_spline_is_opencvs_blender(h, w, levels):
    layers = _layers(h, w, seed=h + w)
    yy, xx = np.mgrid[:h, :w]
    face = (yy - h / 2) ** 2 + (xx - w / 2) ** 2 < (min(h, w) / 3) ** 2
    left = ~face & (xx < w / 2)
    cases = {"partition": [face, left, ~face & ~left],
             "overlap": [face, left | (yy < h // 5), ~face & ~left],
             "gap": [face, left, np.zeros_like(face)]}
    for name, masks in cases.items():
        ours = blend_multiband(layers, masks, levels=levels, method="opencv")
        theirs = blend_multiband(layers, masks, levels=levels, method="opencv-detail")
        assert ours.dtype == np.uint8 and ours.shape == (h, w, 3)
        np.testing.assert_array_equal(ours, theirs, err_msg=name)
