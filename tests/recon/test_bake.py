"""Texture-space rasterisation, interpolation, gap filling and baking."""

import numpy as np
import pytest

from mpeg4 import InputError
from recon.texture.bake import bake, dilate_charts, fill_empty, interpolate, rasterize, rasterize_uv


def _grid(n=6):
    """A unit square split into 2 n² triangles, as texture coordinates."""
    u, v = np.meshgrid(np.linspace(0.05, 0.95, n + 1), np.linspace(0.05, 0.95, n + 1))
    uv = np.c_[u.ravel(), v.ravel()]
    k = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = k[:-1, :-1].ravel(), k[:-1, 1:].ravel(), k[1:, :-1].ravel(), k[1:, 1:].ravel()
    return uv, np.r_[np.c_[a, b, c], np.c_[b, d, c]]


def test_rasterize_covers_the_triangles_once_with_true_barycentric_weights():
    uv, tri = _grid()
    ids, bary = rasterize_uv(uv, tri, (64, 64))
    covered = ids >= 0
    # The square spans texel centres 2.7 .. 60.3: 58 rows and columns inside.
    assert abs(covered.sum() - 58 * 58) <= 2 * 58
    np.testing.assert_allclose(bary[covered].sum(axis=1), 1.0, atol=1e-12)
    assert (bary[covered] >= 0).all()
    # Interpolating the corners' own coordinates gives back each texel's coordinate.
    pos = interpolate(uv, tri, ids, bary)
    ys, xs = np.nonzero(covered)
    np.testing.assert_allclose(pos[ys, xs, 0], (xs + 0.5) / 64, atol=0.5 / 64)
    np.testing.assert_allclose(pos[ys, xs, 1], 1 - (ys + 0.5) / 64, atol=0.5 / 64)


def test_interpolate_reproduces_a_linear_function_exactly_inside():
    uv, tri = _grid()
    ids, bary = rasterize_uv(uv, tri, (80, 80))
    f = 3.0 * uv[:, 0] - 2.0 * uv[:, 1] + 0.5
    out = interpolate(f[:, None], tri, ids, bary)[..., 0]
    ys, xs = np.nonzero(ids >= 0)
    s, t = (xs + 0.5) / 80, 1 - (ys + 0.5) / 80
    inner = (s > 0.06) & (s < 0.94) & (t > 0.06) & (t < 0.94)
    np.testing.assert_allclose(out[ys, xs][inner], 3 * s[inner] - 2 * t[inner] + 0.5, atol=1e-9)


def test_fill_empty_keeps_valid_pixels_and_fills_the_rest_from_them():
    rng = np.random.default_rng(0)
    img = rng.integers(0, 255, (50, 70, 3)).astype(np.uint8)
    valid = np.zeros((50, 70), bool)
    valid[10:20, 30:40] = True
    img[valid] = (200, 100, 50)
    out = fill_empty(img, valid)
    assert (out[valid] == img[valid]).all()
    # Far from the only valid block everything takes its colour.
    assert np.abs(out[~valid].astype(int) - [200, 100, 50]).max() <= 1
    with pytest.raises(InputError, match="no valid pixel"):
        fill_empty(img, np.zeros((50, 70), bool))


def test_dilate_charts_grows_each_chart_with_its_own_colour():
    img = np.zeros((40, 40, 3), np.uint8)
    valid = np.zeros((40, 40), bool)
    img[5:15, 5:15] = (255, 0, 0)
    img[5:15, 25:35] = (0, 0, 255)
    valid[5:15, 5:15] = valid[5:15, 25:35] = True
    out, grown = dilate_charts(img, valid, iterations=3)
    assert grown[2:18, 2:18].all() and not grown[20, 20]
    assert (out[3, 8] == (255, 0, 0)).all() and (out[3, 30] == (0, 0, 255)).all()


def test_bake_onto_the_same_layout_returns_the_texture():
    uv, tri = _grid(8)
    y, x = np.mgrid[0:96, 0:96] / 96.0
    tex = np.clip(np.dstack([x * 255, y * 255, (x * y) * 255]), 0, 255)
    tex = tex.astype(np.uint8)
    out = bake(tex, uv, uv, tri, tri, (96, 96))
    ids, _ = rasterize_uv(uv, tri, (96, 96))
    inner = ids >= 0
    assert np.abs(out[inner].astype(int) - tex[inner].astype(int)).max() <= 2
    # A layout moved by half the square bakes the same picture at the new place.
    shifted = uv * 0.5
    small = bake(tex, uv, shifted, tri, tri, (96, 96))
    ids2, _ = rasterize_uv(shifted, tri, (96, 96))
    ys, xs = np.nonzero(ids2 >= 0)
    expected = tex[np.clip(2 * ys - 96, 0, 95), np.clip(2 * xs, 0, 95)]  # target texel → source texel
    assert np.median(np.abs(small[ys, xs].astype(int) - expected.astype(int))) <= 3


def test_rasterize_refuses_an_empty_image():
    with pytest.raises(InputError, match="empty"):
        rasterize(np.zeros((3, 2)), [[0, 1, 2]], (0, 10))
