"""The neutral lids follow the photo: measured on the front photo, posed by the sculpted
lid shapes, the lids on the eyeball, the FAPU measured on the result."""

import numpy as np
import pytest

from mpeg4.generic_head import load_generic_head
from recon.evaluate.ict import default_ict_path
from recon.evaluate.lids import lid_penetration, visible_opening
from recon.shape.lids import EYES, MIN_OPENING, lid_heights, lid_opening_mm, pose_lids


@pytest.fixture(scope="module")
def generic():
    return load_generic_head()


def test_lid_heights_are_in_eye_widths_whatever_the_roll_and_scale(generic):
    pts = {i: p[:2] for i, p in generic.fp_positions().items()}
    ref = lid_heights(pts)
    a = np.radians(12.0)
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    # The same face as a photo: turned, 4000 px per metre, y down.
    photo = {i: (rot @ p) * [4000.0, -4000.0] + [512.0, 640.0] for i, p in pts.items()}
    got = lid_heights(photo, image=True)
    for eye in EYES:
        assert np.allclose(got[eye], ref[eye], atol=1e-9)
        # The generic head: its opening (9.89 mm) over the eye's width, about 0.38.
        assert 0.3 < ref[eye].sum() < 0.45
        assert ref[eye][0] > 0 and ref[eye][1] > 0


def test_posed_lids_meet_their_heights_on_the_eyeball(generic):
    ref = lid_heights(generic.fp_positions())
    # Left eye: the upper lid half-way down; right eye: the lower lid raised a little.
    target = {"left": ref["left"] * [0.5, 1.0], "right": ref["right"] * [1.0, 0.8]}
    posed, record = pose_lids(generic, target)
    got = lid_heights(posed.fp_positions())
    for eye in EYES:
        assert record[eye]["met"]
        assert np.abs(got[eye] - target[eye]).max() < 0.01
        # The sculpted shapes slide the lids over the eyeball (the generic head's own lids: 0 mm).
        assert lid_penetration(posed, eye) < 0.2
    assert record["left"]["weights"]["eyeBlink_L"] > 0.2 and record["right"]["weights"]["eyeSquint_R"] > 0.1
    # The FAPU are measured on the posed head: IRISD0 is its lids' distance, now smaller.
    opening = lid_opening_mm(posed)
    assert posed.fapu.IRISD0 * 1e3 == pytest.approx(opening["left"], abs=1e-9)
    assert opening["left"] < 0.75 * generic.fapu.IRISD0 * 1e3
    # What a front view shows between the lids follows the feature points.
    assert visible_opening(posed, "left") == pytest.approx(opening["left"], abs=0.8)


def test_a_head_without_the_lid_shapes_is_left_as_it_is(generic):
    bare = generic.copy()
    bare.morph_targets = {}
    same, record = pose_lids(bare, {"left": [0.1, 0.1]})
    assert same is bare and record == {}


pytestmark_ict = pytest.mark.skipif(not default_ict_path().exists(),
                                    reason="needs ../shared/data/ict_facekit/ict_facekit.npz")


@pytest.fixture(scope="module")
def lowered():
    """A synthetic person photographed with the lids 60 % closed, and the heads built from
    the photos' true points with and without posing the neutral lids."""
    from recon.evaluate.synthetic import synthetic_pair
    from recon.shape.fit import fit_head

    pair = synthetic_pair(3, size=(512, 640), texture_size=128, expression={"eyeBlink_L": 0.6, "eyeBlink_R": 0.6})
    heads = {lids: fit_head(pair.fdp, ipd_mm=pair.person.ipd_mm, focal_px=pair.focal_px, neutral_lids=lids)[0]
             for lids in (False, True)}
    return pair.person.head, heads


@pytestmark_ict
def test_the_built_lids_follow_a_lowered_lid_photo(lowered):
    truth, heads = lowered
    before, after = heads[False], heads[True]
    want = lid_opening_mm(truth)
    got = lid_opening_mm(after)
    for eye in EYES:
        seen = visible_opening(truth, eye)
        # Before: the margins pinned as points went into the eyeball, the eye looked open.
        assert visible_opening(before, eye) - seen > 3.0
        # After: what the front view shows is the photo's opening within 0.8 mm (a third
        # of this 2-3 mm opening before: 4.3 mm too open).
        assert visible_opening(after, eye) == pytest.approx(seen, abs=0.8)
        # 0.47 mm short on the left eye when written, 0.65 since the inner corners are
        # de-projected at their own depth, not the side photo's axis (their height 2 mm
        # truer, the lid posed on them a little less open).
        assert got[eye] == pytest.approx(want[eye], abs=0.75)
        assert lid_penetration(after, eye) < 0.45  # 0.22 when written, 0.37 since (as above)
        assert after.metadata["fit"]["lids"][eye]["shapes"][f"eyeBlink_{eye[0].upper()}"] > 0.3
    assert after.fapu.IRISD0 * 1e3 == pytest.approx(got["left"], abs=1e-9)
    assert after.metadata["fit"]["lids"]["posed"] and not before.metadata["fit"]["lids"]["posed"]


@pytestmark_ict
def test_eyes_shut_in_the_photo_still_give_a_head_with_lids_apart(generic):
    from recon.shape.lids import neutral_lids

    # A front photo whose lid margins touch: the start is posed to the smallest opening.
    pts = {i: p[:2] * [4000.0, -4000.0] for i, p in generic.fp_positions().items()}
    for up, low, _, _ in EYES.values():
        pts[up] = pts[low] = 0.5 * (pts[up] + pts[low])
    posed, _, record = neutral_lids(generic, generic.fp_positions(), pts)
    open_eye = lid_heights(generic.fp_positions())
    for eye in EYES:
        assert record[eye]["widened_to"] == MIN_OPENING
        # Apart by at least the smallest opening; no further than the shapes' range leaves
        # them (the squint raises the lower lid only so far: then "met" is False).
        opening = lid_heights(posed.fp_positions())[eye].sum()
        assert MIN_OPENING - 0.015 <= opening < 0.5 * open_eye[eye].sum()
        assert record[eye]["met"] == (abs(opening - MIN_OPENING) <= 0.02)
    assert posed.fapu.IRISD0 > 0.002
