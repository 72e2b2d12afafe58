"""Glasses in the photos (recon.texture.glasses): frames found on a synthetic person who
wears them and inpainted towards the photo without them, nothing found on one who does not,
and the decision over both photos."""

import numpy as np
import pytest

from recon.texture.glasses import GLASSES_COVER, GLASSES_LENGTH, Glasses, remove_glasses, wears_glasses


def _photos(seed, ict_npz):
    from recon.evaluate.synthetic import hard_pair, load_ict

    return hard_pair(seed, data=load_ict(ict_npz), size=(768, 960))


def _remove(sp):
    from mpeg4.render import vertex_normals
    from recon.texture.delight import fit_mask

    head = sp.person.head
    v = head.skin.vertices
    normals = vertex_normals(v, head.skin.triangles)
    seen = {k: np.sum(normals * sp.cameras[k].towards(v), axis=1) > 0 for k in ("front", "side")}
    photos = {"front": sp.front, "side": sp.side}
    return photos, remove_glasses(head, photos, sp.cameras, seen, normals, fit_mask(head) > 0)


@pytest.mark.slow
def test_frames_are_found_and_inpainted_towards_the_photo_without_them(ict_npz):
    """Seed 1 of the harder set wears glasses (gold or black wire frames): most of the
    frames' pixels are found in both photos, most of what is found is frame, and inpainted,
    the frames' pixels on the skin come at least twice as close to the same photo without
    the glasses."""
    import cv2

    from recon.evaluate.synthetic import LABELS, photograph

    sp = _photos(1, ict_npz)
    photos, (out, found) = _remove(sp)
    assert set(found) == {"front", "side"}
    person = sp.person
    dress = person.dress
    person.dress = [(kind, m) for kind, m in dress if kind != "glasses"]
    try:
        for view in ("front", "side"):
            clean, head_mask = photograph(person, sp.cameras[view])
            # The frames over the head (not the rim before the profile, over the backdrop).
            truth = (sp.labels[view] == LABELS["glasses"]) & head_mask
            mask = found[view].mask
            # What is found is widened by the opening's radius (0.035 eye separations), so
            # that the inpainting starts from skin: the frames widened as much, and a pixel.
            r = int(round(0.035 * found[view].ipd_px)) + 1
            near = cv2.dilate(truth.astype(np.uint8), np.ones((2 * r + 1,) * 2, np.uint8)) > 0
            assert (mask & truth).sum() > 0.5 * truth.sum(), view
            assert (mask & near).sum() > 0.75 * mask.sum(), view
            on_skin = truth & mask
            assert on_skin.sum() > 500
            before = np.abs(photos[view][on_skin].astype(float) - clean[on_skin]).mean()
            after = np.abs(out[view][on_skin].astype(float) - clean[on_skin]).mean()
            assert after < 0.5 * before, (view, before, after)
            assert np.array_equal(out[view][~mask], photos[view][~mask])  # nothing else touched
    finally:
        person.dress = dress


@pytest.mark.slow
def test_a_face_without_glasses_is_left_alone(ict_npz):
    sp = _photos(3, ict_npz)  # short hair, skin type IV, clothes, no glasses
    photos, (out, found) = _remove(sp)
    assert found == {}
    assert all(out[k] is photos[k] for k in photos)


def test_the_decision_needs_long_lines_that_ring_the_eyes():
    def g(length, cover):
        return Glasses(np.zeros((4, 4), bool), length, cover, 100.0)

    assert wears_glasses([g(GLASSES_LENGTH * 2, GLASSES_COVER * 2)])
    assert not wears_glasses([])
    # Long lines that do not ring the eyes (a hairline, a crease), and a ring of short bits.
    assert not wears_glasses([g(GLASSES_LENGTH * 3, GLASSES_COVER / 3)])
    assert not wears_glasses([g(GLASSES_LENGTH / 3, GLASSES_COVER * 3)])
    # Both photos weigh in: a clear side photo carries a faint front one.
    assert wears_glasses([g(GLASSES_LENGTH * 2, GLASSES_COVER * 0.9), g(GLASSES_LENGTH * 2, GLASSES_COVER * 1.5)])
