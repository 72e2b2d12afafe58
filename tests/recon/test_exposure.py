"""The side photo's gains (recon.texture.exposure): known gains found back, robust to stray
pixels, no correction without evidence."""

import numpy as np
import pytest

from recon.texture.exposure import GAIN_RANGE, MIN_SAMPLES, apply_gain, side_gain


def _pair(gain, n=400, seed=0):
    """A front photo of skin-coloured noise, a side photo showing the same skin divided by
    ``gain`` at other pixels, and the pixels of n shared points in each."""
    rng = np.random.default_rng(seed)
    front = np.clip(rng.normal((180, 130, 110), 12, (200, 300, 3)), 0, 255).astype(np.uint8)
    fpx = np.c_[rng.integers(0, 300, n), rng.integers(0, 200, n)].astype(float)
    spx = np.c_[rng.integers(0, 300, n), rng.integers(0, 200, n)].astype(float)
    side = np.zeros_like(front)
    side[spx[:, 1].astype(int), spx[:, 0].astype(int)] = np.clip(
        np.rint(front[fpx[:, 1].astype(int), fpx[:, 0].astype(int)] / np.asarray(gain)), 0, 255)
    return front, side, fpx, spx


def test_the_gain_between_two_exposures_is_found_back():
    gain = np.array([1.25, 1.1, 0.9])
    front, side, fpx, spx = _pair(gain)
    # A few hundred points: the median's error is well under 1 % at this noise (the
    # rounding to grey levels is 0.3 % of 150).
    got = side_gain(front, side, fpx, spx, np.ones(len(fpx), bool))
    np.testing.assert_allclose(got, gain, rtol=0.01)
    # The scaled side photo agrees with the front one where both show the skin.
    scaled = apply_gain(side, got)
    a = front[fpx[:, 1].astype(int), fpx[:, 0].astype(int)].astype(float)
    b = scaled[spx[:, 1].astype(int), spx[:, 0].astype(int)].astype(float)
    assert np.abs(np.median(a - b, axis=0)).max() <= 2.0


def test_stray_pixels_do_not_move_it():
    """A fifth of the shared points on something else (hair, a wrong pixel) in the side
    photo: the ratio of medians holds within 5 % where a ratio of means is off by 15 %."""
    gain = np.array([1.2, 1.2, 1.2])
    front, side, fpx, spx = _pair(gain, seed=1)
    stray = np.arange(len(spx)) % 5 == 0
    side[spx[stray, 1].astype(int), spx[stray, 0].astype(int)] = 30  # dark hair
    got = side_gain(front, side, fpx, spx, np.ones(len(fpx), bool))
    np.testing.assert_allclose(got, gain, rtol=0.05)
    a = front[fpx[:, 1].astype(int), fpx[:, 0].astype(int)].astype(float).mean(axis=0)
    b = side[spx[:, 1].astype(int), spx[:, 0].astype(int)].astype(float).mean(axis=0)
    assert np.all(a / b > 1.15 * gain)


def test_no_evidence_no_correction_and_wild_gains_are_clipped():
    front, side, fpx, spx = _pair(np.array([1.3, 1.3, 1.3]))
    few = np.zeros(len(fpx), bool)
    few[: MIN_SAMPLES - 1] = True
    assert np.array_equal(side_gain(front, side, fpx, spx, few), np.ones(3))
    # Points outside the photos and burnt-out pixels carry nothing.
    off = spx + 1000.0
    assert np.array_equal(side_gain(front, side, fpx, off, np.ones(len(fpx), bool)), np.ones(3))
    dark = side // 4
    got = side_gain(front, np.maximum(dark, 9), fpx, spx, np.ones(len(fpx), bool))
    assert np.all(got == GAIN_RANGE[1])


@pytest.mark.parametrize("gain", [(1.0, 1.0, 1.0), (2.0, 0.5, 1.5)])
def test_apply_gain_rounds_and_clips(gain):
    photo = np.array([[[0, 100, 200], [255, 3, 170]]], np.uint8)
    got = apply_gain(photo, np.array(gain))
    want = np.clip(np.rint(photo * np.array(gain)), 0, 255)
    assert got.dtype == np.uint8 and np.array_equal(got, want)
