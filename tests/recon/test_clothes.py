"""The neck below the collar (recon.texture.clothes): the shirt found, the skin above it
carried down; and on a dressed synthetic person, the neck's texture against its paint."""

import numpy as np
import pytest

from recon.texture.clothes import clothes_mask, fill_from_skin, skin_model, skin_pixels

SKIN = np.array([196.0, 150.0, 128.0])
SHIRT = np.array([40.0, 60.0, 130.0])


def _neck_photo(seed=0):
    """A 200 x 160 photo: skin everywhere in the head's region, a shirt over the bottom
    rows with an open V in the middle, a dark speck of stubble on the neck, and a
    backdrop on the left and right edges."""
    rng = np.random.default_rng(seed)
    h, w = 200, 160
    shade = np.linspace(1.0, 0.85, h)[:, None, None]  # darker down the neck
    photo = SKIN * shade + rng.normal(0, 5, (h, w, 3))
    ys, xs = np.mgrid[:h, :w]
    collar = 130 + np.clip(30 - np.abs(xs - 80), 0, None)  # the V's tip at row 160
    shirt = ys >= collar
    photo[shirt] = SHIRT + rng.normal(0, 6, (shirt.sum(), 3))
    photo[90:93, 60:63] = (60, 45, 40)  # stubble
    head = np.ones((h, w), bool)
    head[:, :10] = head[:, -10:] = False
    photo[~head] = (220, 222, 226)
    return np.clip(photo, 0, 255).astype(np.uint8), head, shirt & head


def test_the_shirt_is_found_and_the_skin_is_not():
    photo, head, shirt = _neck_photo()
    face = np.c_[np.repeat(np.arange(20, 140, 6), 8), np.tile(np.arange(20, 60, 5), 20)]  # (x, y) above
    model = skin_model(photo, face)
    mask = clothes_mask(photo, head, model, chin_row=40.0)
    assert mask[shirt].mean() > 0.97
    skin = head & ~shirt
    assert mask[skin].mean() < 0.01  # the V and the stubble stay skin
    assert not mask[:40].any()  # nothing above the chin


def test_the_fill_has_the_necks_colour_and_grain():
    photo, head, shirt = _neck_photo(1)
    face = np.c_[np.repeat(np.arange(20, 140, 6), 8), np.tile(np.arange(20, 60, 5), 20)]
    model = skin_model(photo, face)
    mask = clothes_mask(photo, head, model, chin_row=40.0)
    skin = np.zeros_like(mask)
    skin[40:] = head[40:] & skin_pixels(photo, model, slice(40, None)) & ~mask[40:]
    out = fill_from_skin(photo, mask, skin)
    assert np.array_equal(out[~mask], photo[~mask])  # nothing else touched
    filled = out[mask].astype(float)
    neck = photo[100:130, 20:140].reshape(-1, 3).astype(float)  # the skin right above the collar
    assert np.abs(filled.mean(axis=0) - neck.mean(axis=0)).max() < 4.0
    # The grain is the skin's own (5 grey levels of noise), not a smooth wash nor the shirt.
    assert 0.7 < filled.std(axis=0).mean() / neck.std(axis=0).mean() < 1.5
    # As much of it passes for skin by the face's model as the neck's own skin does.
    assert skin_pixels(out, model)[mask].mean() > skin_pixels(photo, model)[100:130, 20:140].mean() - 0.03


def test_the_fill_carries_the_shading_in_from_all_round():
    # Skin shaded across and down (30 and 40 grey levels), with grain, round a patch of
    # cloth: the fill's shading is the plane the skin around it lies on (Laplace's equation
    # keeps a plane), its grain as strong as the skin's, and nothing steps at its rim.
    import cv2

    rng = np.random.default_rng(3)
    h, w = 160, 200
    ys, xs = np.mgrid[:h, :w].astype(float)
    plane = SKIN[None, None] - (30.0 * xs / w + 40.0 * ys / h)[..., None]
    photo = np.clip(plane + rng.normal(0, 4, (h, w, 3)), 0, 255).astype(np.uint8)
    mask = np.zeros((h, w), bool)
    mask[50:120, 60:150] = True
    photo[mask] = SHIRT.astype(np.uint8)
    out = fill_from_skin(photo, mask, ~mask)
    assert np.array_equal(out[~mask], photo[~mask])
    smooth = cv2.GaussianBlur(out.astype(np.float32), (0, 0), 4.0)
    inner = np.zeros_like(mask)
    inner[60:110, 70:140] = True  # away from the rim, where the blur would mix in the skin
    assert np.abs(smooth[inner] - plane[inner]).mean() < 2.0
    grain = (out.astype(float) - plane)[mask]
    assert 0.7 < grain.std(axis=0).mean() / 4.0 < 1.3
    # Across the rim, a step no larger than the grain's between neighbours in the skin.
    rim = np.abs(out[50:120, 59].astype(float) - out[50:120, 60]).mean() + \
        np.abs(out[50:120, 150].astype(float) - out[50:120, 149]).mean()
    skin = np.abs(out[10:40, 59].astype(float) - out[10:40, 60]).mean() + \
        np.abs(out[10:40, 150].astype(float) - out[10:40, 149]).mean()
    assert rim < 1.5 * skin


def test_no_skin_no_model_and_nothing_to_fill():
    photo, head, _ = _neck_photo()
    assert skin_model(photo, np.array([[5.0, 5.0]] * 10)) is None
    assert skin_model(photo, np.full((50, 2), -100.0)) is None  # outside the photo
    none = np.zeros(head.shape, bool)
    assert fill_from_skin(photo, none, head) is photo


def _neck_and_face_error(result, sp, data):
    """Mean absolute colour error (grey levels) of the texture against the painted skin on
    the neck (3 cm and more below the chin) and on the face's skin, up to the albedo's level."""
    from scipy.ndimage import map_coordinates

    from recon.evaluate.synthetic import skin_albedo

    skin = result.skin
    tex = result.head.parts["skin"].texture.astype(np.float32)
    size = tex.shape[0]
    x = (skin.uv[:, 0] * size - 0.5).astype(np.float32)
    y = ((1 - skin.uv[:, 1]) * size - 0.5).astype(np.float32)
    got = np.stack([map_coordinates(tex[..., c], [y, x], order=1) for c in range(3)], axis=1)
    want = np.asarray(skin_albedo(sp.person, data), float)[skin.source]
    v = result.head.parts["skin"].vertices
    chin = result.head.fp_position("2.1")[1]
    ok = np.all(np.isfinite(want), axis=1) & (skin.vertex_region < 3)  # front, seen, mirrored
    neck = ok & (v[:, 1] < chin - 0.03)
    face = ok & (v[:, 1] > chin) & (np.linalg.norm(want - sp.person.skin_rgb, axis=1) < 45)
    luma = np.array([0.299, 0.587, 0.114])
    gain = np.median((want[face] @ luma) / np.maximum(got[face] @ luma, 4))  # the albedo's level
    err = np.abs(got * gain - want)
    assert neck.sum() > 300 and face.sum() > 3000
    return err[neck].mean(), err[face].mean()


@pytest.mark.slow
def test_a_shirt_is_not_painted_on_the_neck(ict_npz, monkeypatch):
    """A synthetic person in a shirt with a collar (recon.evaluate.dressing), textured with
    and without the fill: the neck below the chin against the painted skin. With the shirt
    painted on it, 70 grey levels off; filled, 5.7 (no shirt: 5; rows of skin copied down
    each column, after the light was fitted, left it 44). The fill comes before the light
    is fitted, so the face gains too: off by 32 with the shirt in the fit, 11
    without."""
    import recon.texture.skin as skin_module
    from recon.build import PhotoPair, build_head
    from recon.evaluate.dressing import Look
    from recon.evaluate.synthetic import load_ict, synthetic_pair

    data = load_ict(ict_npz)
    sp = synthetic_pair(1000, data=data, look=Look(clothes=True))
    pair = PhotoPair(sp.front, sp.side, sp.fdp, {})
    said = []
    filled = build_head(pair, ipd_mm=sp.person.ipd_mm, focal_px=sp.focal_px, texture_size=1024,
                        progress=said.append)
    assert any("clothes over" in s and "front photo" in s for s in said), said
    monkeypatch.setattr(skin_module, "remove_clothes", lambda head, photo, *a, **k: (photo, 0.0))
    painted = build_head(pair, ipd_mm=sp.person.ipd_mm, focal_px=sp.focal_px, texture_size=1024)
    neck, face = _neck_and_face_error(filled, sp, data)
    neck0, face0 = _neck_and_face_error(painted, sp, data)
    assert neck < 0.25 * neck0, (neck, neck0)
    assert face < 0.5 * face0, (face, face0)
