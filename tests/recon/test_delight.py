"""De-lighting: the spherical-harmonic shading fit, and the albedo texture against the truth."""

import numpy as np
import pytest

from recon.texture.delight import MIN_SHADING, fit_lighting, sh_basis


def _sphere_photo(light, ambient, size=200, albedo=(200.0, 150.0, 120.0), seed=0):
    """A lit sphere seen from the front: its normals, mask, and a photo of a slightly
    mottled albedo with dark blotches (hair, brows) the fit must shrug off."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:size, 0:size]
    x = (xx - size / 2 + 0.5) / (size / 2 - 2)
    y = -(yy - size / 2 + 0.5) / (size / 2 - 2)
    mask = x * x + y * y < 1.0
    z = np.sqrt(np.clip(1 - x * x - y * y, 0, 1))
    n = np.where(mask[..., None], np.stack([x, y, z], axis=-1), 0.0).astype(np.float32)
    l = np.asarray(light, float) / np.linalg.norm(light)
    shade = ambient + (1 - ambient) * np.clip(n @ l, 0, None)
    alb = np.asarray(albedo) * (1 + 0.03 * rng.standard_normal((size, size, 1)))
    blotch = rng.random((size, size)) < 0.08
    alb[blotch] *= 0.3
    photo = np.clip(alb * shade[..., None], 0, 255)
    photo[~mask] = 220
    return photo.astype(np.uint8), n, mask, shade, alb, blotch


@pytest.mark.parametrize("light", [(-0.35, 0.45, 1.0), (0.6, -0.2, 0.8), (0.0, 0.9, 0.5)])
def test_fitted_shading_follows_any_light_and_ignores_blotches(light):
    photo, n, mask, shade, _, blotch = _sphere_photo(light, 0.4)
    lit = fit_lighting(photo, n, mask, mask.astype(np.float32))
    # The shading's shape, whatever the light (the fit is never told it): the fitted shading
    # over the true one is the same everywhere up to the scale the fit cannot know. An
    # order-2 fit of a clamped cosine is within ~6% (Ramamoorthi & Hanrahan).
    face = mask & (shade > 0.5) & ~blotch
    ratio = lit.shading[face] / shade[face]
    assert np.std(ratio) / np.mean(ratio) < 0.06, np.std(ratio) / np.mean(ratio)
    assert lit.inlier_share > 0.85  # the blotches (8 %) fall to the robust weights
    # The scale: the albedo keeps the photo's median skin brightness where the skin faces
    # the camera within 45° (over the skin the fit kept: not the blotches, every third
    # pixel each way; here over all of it).
    luma = photo.astype(float) @ np.array([0.299, 0.587, 0.114])
    skin = mask & ~blotch & (n[..., 2] > np.cos(np.radians(45.0)))
    assert abs(np.median(luma[skin] / lit.shading[skin]) / np.median(luma[skin]) - 1.0) < 0.03
    # Held at MIN_SHADING of its brightest (1.25 at most) where the light grazes; 1 off the head.
    assert lit.shading[mask].min() / lit.shading[mask].max() >= MIN_SHADING / 1.25 - 1e-6
    assert np.all(lit.shading[~mask] == 1.0)
    # Dividing it out flattens the light: the albedo varies far less than the photo.
    flat = photo[face].astype(float).mean(axis=1) / lit.shading[face]
    assert np.std(flat) / np.mean(flat) < 0.5 * np.std(photo[face].astype(float).mean(axis=1)) / \
        np.mean(photo[face].astype(float).mean(axis=1))


def test_the_albedo_keeps_the_face_s_brightness_not_the_neck_s():
    # Lit from above, the lower part of the sphere (a neck in the chin's shadow) is dark:
    # held to all the facing skin, the upper part's albedo comes out 14 % darker than its
    # photo; held to the face (the rows above the "chin"), within 3 %.
    photo, n, mask, _, _, blotch = _sphere_photo((0.0, 0.9, 0.5), 0.3)
    face = np.zeros_like(mask)
    face[: int(0.6 * len(face))] = True
    luma = photo.astype(float) @ np.array([0.299, 0.587, 0.114])
    skin = mask & ~blotch & (n[..., 2] > np.cos(np.radians(45.0))) & face

    def level(**kw):
        lit = fit_lighting(photo, n, mask, mask.astype(np.float32), **kw)
        return np.median(luma[skin] / lit.shading[skin]) / np.median(luma[skin])

    assert abs(level(face=face) - 1.0) < 0.03
    assert level() < 0.9


def test_the_basis_is_the_nine_harmonics():
    n = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    np.testing.assert_allclose(sh_basis(n), [[1, 0, 0, 1, 0, 0, 0, 0, 2], [1, 1, 0, 0, 0, 0, 0, 1, -1],
                                             [1, 0, 1, 0, 0, 0, 0, -1, -1]])


@pytest.mark.slow
def test_the_albedo_texture_gives_back_the_paint_where_the_lit_one_is_dark(ict_npz):
    """The example (ICT identity 5): its texture against the painted skin at every vertex."""
    from recon.build import build_head, load_pair
    from recon.example import EXAMPLE_FDP, example_camera
    from recon.evaluate.fidelity import albedo_error
    from recon.evaluate.synthetic import load_ict, make_person, skin_albedo

    data = load_ict(ict_npz)
    person = make_person(5, data)
    truth = skin_albedo(person, data)
    cam = example_camera()
    pair = load_pair(EXAMPLE_FDP)
    err = {}
    for keep in (True, False):
        r = build_head(pair, ipd_mm=cam["ipd_mm"], focal_px=cam["focal_px"], texture_size=1024, keep_lighting=keep)
        err[keep] = albedo_error(r.head, r.skin, truth, r.cameras["side"], skin_tone=person.skin_rgb, albedo_gain=not keep)
        assert r.head.metadata["build"]["texture_lighting"] == ("photo" if keep else "albedo")
    lit, alb = err[True], err[False]
    # At 1024²: the face as a whole is off the paint by 32 grey levels in the lit texture
    # (33 darker: the light moving with the cameras comes from the left), by 8 in the albedo
    # one; the error of the face's left-right difference 24 vs 5. The cheek in front of the
    # ear comes from the side photo, which faces it: 17 off in the lit texture, 4 de-lit (when
    # the texture took it from the front photo, which sees it at a grazing angle: 49 and 8),
    # its step in brightness against the front of the face +17 lit (the side photo's light
    # falls on it squarely), +3 de-lit.
    assert lit.vertices["cheek"] > 400 and lit.vertices["face"] > 6000
    assert alb.mae["cheek"] < 8.0 and lit.mae["cheek"] > 12.0, (alb.mae, lit.mae)
    assert alb.mae["face"] < 12.0 and lit.mae["face"] > 25.0, (alb.mae, lit.mae)
    assert abs(alb.cheek_minus_front) < 8.0 and abs(lit.cheek_minus_front) > 12.0, (alb.bias, lit.bias)
    assert alb.left_right < 11.0 and lit.left_right > 18.0, (alb.left_right, lit.left_right)


def test_a_de_lit_photo_is_judged_before_it_is_used():
    from recon.texture.delight import Lighting, judge

    photo = np.full((20, 20, 3), 90, np.uint8)
    skin = np.zeros((20, 20), bool)
    skin[5:15, 5:15] = True
    fine = Lighting(np.zeros(9), 100.0, np.ones((20, 20), np.float32), skin, 100, 1.0, mean=0.8)
    assert judge(photo, photo, fine, skin) is None
    dark = Lighting(np.zeros(9), 100.0, np.ones((20, 20), np.float32), skin, 100, 1.0, mean=0.2)
    assert "deep shadow" in judge(photo, photo, dark, skin)
    burnt = photo.copy()
    burnt[5:8, 5:15] = 255  # 30 % of the skin white where the photo was not
    assert "burn 30% of the skin" in judge(photo, burnt, fine, skin)


def test_relighting_the_albedo_gives_back_the_photo_s_skin_tone():
    """The real-photo benchmark's relit skin colour: the de-lit photo times the fitted
    shading is the photo again (to rounding), so its CIEDE2000 to the photo is ~0, while
    the albedo alone differs by the light the fit took out."""
    from types import SimpleNamespace

    from skimage.color import deltaE_ciede2000, rgb2lab

    from recon.evaluate.real_photos import relit

    photo, n, mask, shade, _, blotch = _sphere_photo((0.5, 0.4, 0.8), 0.35)
    lit = fit_lighting(photo, n, mask, mask.astype(np.float32))
    albedo = np.clip(np.round(photo / lit.shading[..., None]), 0, 255).astype(np.uint8)
    back = relit(albedo, lit)
    face = mask & lit.trust & ~blotch

    def median_de(a, b):
        lab = rgb2lab(np.array([[np.median(a[face], axis=0), np.median(b[face], axis=0)]]) / 255.0)[0]
        return float(deltaE_ciede2000(lab[0], lab[1]))

    assert median_de(back, photo) < 0.5
    assert np.abs(back[face].astype(int) - photo[face]).max() <= 3
    # A texture that kept the light (the build's fallback) is already lit as the photo is.
    assert relit(photo, SimpleNamespace(fallback="implausible", shading=lit.shading)) is photo
    assert relit(albedo, SimpleNamespace(fallback=None, shading=lit.shading[1:])) is None


def test_burnt_pixels_are_the_ones_de_lighting_burnt_at_the_outline():
    """A de-lit pixel near the person's outline saturated where the photo was not is burnt
    (grown by two pixels into its glow, within the person); a white the photo itself shows
    (a shirt's stripe), a highlight inside the face and whatever lies outside the person
    are not."""
    from recon.texture.delight import burnt_pixels

    photo = np.full((400, 600, 3), 120, np.uint8)
    albedo = photo.copy()
    person = np.zeros((400, 600), bool)
    person[50:350, 50:450] = True
    albedo[200, 60] = 255             # burnt at the outline: the photo's 120 divided by too little
    photo[60, 300] = albedo[60, 300] = 255  # white in the photo: kept
    albedo[200, 250] = 255            # a highlight inside: left
    albedo[200, 500] = 255            # outside the person
    burnt = burnt_pixels(photo, albedo, person)
    assert burnt[200, 60] and burnt[200, 62] and burnt[198, 60] and not burnt[200, 63]
    assert not burnt[60, 300] and not burnt[200, 250] and not burnt[200, 500]
    assert burnt[198:203, 58:63].sum() == burnt.sum() >= 13  # within two pixels of it
