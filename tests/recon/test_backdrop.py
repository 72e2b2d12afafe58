"""What the texture takes from a photo: the person, not the backdrop beside a skull the
fitted head overhangs (recon.texture.skin with the selfie segmentation)."""

import numpy as np
import pytest


@pytest.mark.slow
def test_the_texture_takes_the_person_not_the_wall_beside_it(ict_npz, monkeypatch):
    """A patch of the side photo over the back of the skull that the segmentation says is
    not the person (a wall the head overhangs, painted pure green here) is filled from
    the person around it, not painted on the skull; without the segmentation it is."""
    pytest.importorskip("mediapipe")
    import recon.landmarks.models as models
    import recon.texture.skin as skin_module
    from recon.build import PhotoPair, build_head
    from recon.evaluate.synthetic import load_ict, synthetic_pair

    sp = synthetic_pair(1000, data=load_ict(ict_npz))
    side = sp.side.copy()
    # The skull's back in the side photo: behind the ear, above its middle.
    pts = sp.fdp.views["side"].points
    ear = np.mean([pts[i] for i in ("10.1", "10.2", "10.5", "10.6") if i in pts], axis=0)
    h, w = side.shape[:2]
    back = np.sign(ear[0] - pts["9.3"][0])  # away from the nose
    x0, x1 = sorted((int(ear[0] + back * 0.02 * w), int(ear[0] + back * 0.25 * w)))
    patch = np.zeros((h, w), bool)
    patch[max(int(ear[1] - 0.18 * h), 0):int(ear[1] - 0.02 * h), max(x0, 0):min(x1, w)] = True
    side[patch] = (0, 255, 0)
    real = models.person_mask

    def person(image):
        mask = real(image)
        if image.shape == side.shape and np.array_equal(image, side):
            mask = mask.copy()
            mask[patch] = 0.0
        return mask

    monkeypatch.setattr(models, "person_mask", person)
    pair = PhotoPair(sp.front, side, sp.fdp, {})

    def green_share():
        tex = build_head(pair, ipd_mm=sp.person.ipd_mm, focal_px=sp.focal_px, texture_size=512,
                         keep_lighting=True).head.parts["skin"].texture.astype(int)
        return float(np.mean((tex[..., 1] > 200) & (tex[..., 0] < 80) & (tex[..., 2] < 80)))

    with_segmentation = green_share()
    monkeypatch.setattr(skin_module, "_person", lambda photo, head_mask: head_mask)
    without = green_share()
    # Without it 7 % of the texture is the patch's green; with it, none.
    assert without > 0.02, without
    assert with_segmentation < 0.05 * without, (with_segmentation, without)
