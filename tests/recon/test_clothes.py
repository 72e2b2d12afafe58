"""The neck below the collar (recon.texture.clothes): the shirt found, the skin above it
carried down; and on a dressed synthetic person, the neck's texture against its paint."""

import numpy as np
import pytest

from recon.texture.clothes import SKIN_CHI2, clothes_mask, fill_from_skin, skin_model, skin_pixels

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


@pytest.mark.slow
def test_hair_hanging_over_the_nape_is_not_painted_on_the_neck(ict_npz, monkeypatch):
    """Strands of dark hair drawn down the neck behind the jaw in the side photo (as long
    hair falls there) are painted as the skin around them (recon.texture.clothes.nape_zone);
    without that step they are painted on the neck (0.17 of the skin under the ears behind
    the jaw's angle takes their colour; filled, none)."""
    import cv2
    from scipy.ndimage import map_coordinates

    import recon.texture.clothes as clothes
    from recon.build import PhotoPair, build_head
    from recon.evaluate.synthetic import load_ict, synthetic_pair

    sp = synthetic_pair(1000, data=load_ict(ict_npz))
    pts = sp.fdp.views["side"].points
    lobe = np.mean([pts[i] for i in ("10.5", "10.6") if i in pts], axis=0)
    back = np.sign(lobe[0] - pts["9.3"][0])  # away from the nose
    front = sp.fdp.views["front"].points
    # The strands' scale, pixels: 0.7 of the distance between the pupils (147 px, as the
    # lobe's distance from the old jaw point, mid-cheek, gave; from the gonion, 20 mm in
    # front of the lobe, the strands would end above most of the neck).
    reach = 0.7 * float(np.linalg.norm(front["3.5"] - front["3.6"]))
    side = sp.side.copy()
    rng = np.random.default_rng(0)
    hair = (70, 45, 30)
    for _ in range(30):  # wavy strands from under the ear lobe down the neck
        x0 = lobe[0] + back * rng.uniform(0.3, 1.6) * reach
        ys = np.linspace(lobe[1] + 5, lobe[1] + rng.uniform(3, 5) * reach, 40)
        xs = x0 + back * np.linspace(0, 0.5, 40) * reach + 4 * np.sin(ys / 9 + rng.uniform(0, 6))
        cv2.polylines(side, [np.rint(np.c_[xs, ys]).astype(np.int32)], False, hair, 3, cv2.LINE_AA)
    pair = PhotoPair(sp.front, side, sp.fdp, {})

    def hair_on_the_nape():
        r = build_head(pair, ipd_mm=sp.person.ipd_mm, focal_px=sp.focal_px, texture_size=1024, keep_lighting=True)
        tex = r.head.parts["skin"].texture.astype(np.float32)
        s, v = r.skin, r.head.parts["skin"].vertices
        size = tex.shape[0]
        jaw3 = 0.5 * (r.head.fp_position("2.13") + r.head.fp_position("2.14"))
        lobe3 = 0.5 * (r.head.fp_position("10.5") + r.head.fp_position("10.6"))
        sv = v[s.source]
        # Under the ears, behind the jaw's angle, seen by the side photo.
        nape = (sv[:, 1] < lobe3[1]) & (sv[:, 2] < jaw3[2]) & (s.vertex_region == 1)
        x = s.uv[nape, 0] * size - 0.5
        y = (1 - s.uv[nape, 1]) * size - 0.5
        got = np.stack([map_coordinates(tex[..., c], [y, x], order=1) for c in range(3)], axis=1)
        assert nape.sum() > 200
        return float(np.mean(np.linalg.norm(got - hair, axis=1) < 40))

    filled = hair_on_the_nape()
    monkeypatch.setattr(clothes, "nape_zone", lambda head, camera, depth, within=None: np.zeros(depth.shape, bool))
    painted = hair_on_the_nape()
    assert painted > 0.08, painted  # 0.17 of the nape the side photo gives
    assert filled < 0.2 * painted, (filled, painted)


def test_the_face_skin_model_grows_from_the_cheeks_past_fair_hair():
    """Fair hair over a third of the face (a fringe, the temples) is near enough to skin
    to widen one Gaussian over both; grown from the cheeks, the model keeps the skin and
    leaves the hair out."""
    from mpeg4.camera import Camera
    from mpeg4.generic_head import load_generic_head
    from mpeg4.render import RenderMesh
    from mpeg4.unlit import render_depth
    from recon.texture.clothes import _lab, cheek_vertices, face_skin_model
    from recon.texture.regions import _visible

    head = load_generic_head()
    v = head.skin.vertices
    cam = Camera.fit(v, 400, 500, focal_px=1500.0)
    depth = render_depth([RenderMesh(p.vertices, p.triangles) for p in head.parts.values()], cam)
    seen = _visible(v, cam, depth)
    rng = np.random.default_rng(2)
    h, w = depth.shape
    photo = np.full((h, w, 3), 230.0)
    photo[np.isfinite(depth)] = SKIN
    hair_rgb = np.array([170.0, 125.0, 85.0])  # dark blond: 9 L darker and yellower than the skin
    brow = cam.project(head.fp_position("4.1")[None])[0, 1]
    hair = np.isfinite(depth) & (np.arange(h)[:, None] < brow - 4)
    photo[hair] = hair_rgb
    photo = np.clip(photo + rng.normal(0, 6, photo.shape), 0, 255).astype(np.uint8)
    assert cheek_vertices(head)[seen].sum() > 100
    mean, inv = face_skin_model(head, photo, cam, seen)
    d_hair = _lab(hair_rgb.astype(np.uint8)[None])[0] - mean
    d_skin = _lab(SKIN.astype(np.uint8)[None])[0] - mean
    assert d_hair @ inv @ d_hair > 2 * SKIN_CHI2  # the hair is far outside
    assert d_skin @ inv @ d_skin < 1.0  # the skin at its centre
    assert skin_pixels(photo, (mean, inv))[hair].mean() < 0.01
    assert skin_pixels(photo, (mean, inv))[np.isfinite(depth) & ~hair].mean() > 0.97


def test_a_collar_band_low_on_the_neck_is_found_and_a_beard_under_the_chin_is_not():
    """A white undershirt's rim across the base of the neck, above a sweater of the skin's
    own colour (nothing rises from the bottom as clothes), reaching the nape zone at both
    ends: found whole. A dark band of beard just under the chin, reaching it too: left."""
    from recon.texture.clothes import collar_bands

    h, w = 200, 160
    ys, xs = np.mgrid[:h, :w]
    other = np.zeros((h, w), bool)
    rim = (np.abs(ys - (150 - 0.004 * (xs - 80) ** 2)) < 4) & (xs > 20) & (xs < 140)  # an arc, 7 px wide
    beard = (ys > 42) & (ys < 60) & (xs > 25) & (xs < 135)
    other |= rim | beard
    nape = (xs < 35) | (xs > 125)  # the neck's sides behind the jaw
    nape[:40] = False
    found = collar_bands(other, nape, chin_row=40.0)
    assert found[rim].all()
    assert not found[beard].any()
    assert found.sum() < 1.6 * rim.sum()  # the band and its rim, nothing more
    # A band that reaches no nape (the neck's front only) is left for clothes_mask to judge.
    assert not collar_bands(other & (np.abs(xs - 80) < 30), nape, chin_row=40.0).any()
