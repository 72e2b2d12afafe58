"""The harder synthetic set: hair with volume, skin types, clothes, glasses, busy backgrounds."""

import numpy as np
import pytest

from recon.evaluate.dressing import (BACKGROUNDS, FITZPATRICK_LAB, Look, background_image, fitzpatrick_rgb,
                                     hard_look, ita_degrees)
from recon.evaluate.synthetic import LABELS

SIZE = (400, 500)


def _pair(ict_npz, seed, look):
    from recon.evaluate.synthetic import load_ict, synthetic_pair

    return synthetic_pair(seed, size=SIZE, data=load_ict(ict_npz), texture_size=256, look=look)


@pytest.fixture(scope="module")
def bushy(ict_npz):
    return _pair(ict_npz, 4, Look(hair="bushy", skin_type=6, clothes=True, glasses=True, background="cluttered"))


@pytest.fixture(scope="module")
def ponytail(ict_npz):
    return _pair(ict_npz, 5, Look(hair="ponytail", skin_type=1, clothes=True, background="textured"))


def test_skin_types_lie_in_their_ita_bands_and_darken_in_order():
    bands = {1: (55, 90), 2: (41, 55), 3: (28, 41), 4: (10, 28), 5: (-30, 10), 6: (-90, -30)}
    for t, lab in FITZPATRICK_LAB.items():
        lo, hi = bands[t]
        assert lo < ita_degrees(lab) < hi, t
    from skimage.color import rgb2lab

    lightness = [rgb2lab(fitzpatrick_rgb(t)[None, None] / 255.0)[0, 0, 0] for t in range(1, 7)]
    assert np.all(np.diff(lightness) < -3)
    with pytest.raises(ValueError, match="1–6"):
        fitzpatrick_rgb(7)


def test_six_consecutive_seeds_hold_every_type_and_every_style_twice():
    looks = [hard_look(s) for s in range(10, 16)]
    assert sorted(lk.skin_type for lk in looks) == [1, 2, 3, 4, 5, 6]
    for style in ("short", "bushy", "ponytail"):
        assert sum(lk.hair == style for lk in looks) == 2
    assert {lk.background for lk in looks} == {"textured", "cluttered"} and all(lk.clothes for lk in looks)
    with pytest.raises(ValueError, match="hair style"):
        Look(hair="mohawk")


def test_backgrounds_are_busy_except_the_plain_wall():
    for kind in BACKGROUNDS:
        img = background_image(kind, 200, 250, 3)
        assert img.shape == (250, 200, 3) and img.dtype == np.uint8
        grad = np.abs(np.diff(img.astype(float), axis=1)).mean()
        assert (grad < 0.5) if kind == "plain" else (grad > 1.0), (kind, grad)


def test_bushy_hair_raises_the_skull_and_11_5_is_on_its_top(bushy):
    head = bushy.person.head
    top = bushy.fdp.views["front"].points["11.5"]
    skull = bushy.cameras["front"].project(head.fp_position("11.4")[None])[0]
    px_per_m = np.linalg.norm(bushy.fdp.views["front"].points["3.5"] - bushy.fdp.views["front"].points["3.6"]) / (
        bushy.person.ipd_mm / 1000)
    assert (skull[1] - top[1]) / px_per_m > 0.02  # at least 2 cm of hair over the skull
    lab = bushy.labels["front"]
    x, y = int(round(top[0])), int(round(top[1]))
    assert lab[y + 3, x] == LABELS["hair"]
    # On the silhouette's top or under a curl rising above it, not above the hair.
    assert 0 <= (y - np.flatnonzero(lab[:, x])[0]) / px_per_m < 0.015


def test_labels_cover_what_the_photo_shows(bushy, ponytail):
    for pair in (bushy, ponytail):
        for view in ("front", "side"):
            lab, mask = pair.labels[view], pair.masks[view]
            # Labels and the depth mask are the same drawing (only antialiased edges differ).
            assert np.mean((lab > 0) != mask) < 0.01
            chin = pair.fdp.views[view].points["2.1"]
            clothes = np.argwhere(lab == LABELS["clothes"])
            assert len(clothes) and clothes[:, 0].min() > chin[1]  # clothes only below the chin
    # Glasses in front of the eyes: across the pupils' row between them.
    lab = bushy.labels["front"]
    p = bushy.fdp.views["front"].points
    row = int(round(p["3.5"][1]))
    assert np.any(lab[row - 15:row + 15, int(p["3.6"][0]):int(p["3.5"][0])] == LABELS["glasses"])
    # The ponytail shows behind the head in the profile, not in front of the face.
    side = ponytail.labels["side"]
    back = ponytail.fdp.views["side"].points["11.6"]
    hair_cols = np.argwhere(side == LABELS["hair"])[:, 1]
    assert hair_cols.max() > back[0] + 5


def test_the_background_is_the_drawn_wall_away_from_the_person(bushy):
    wall = background_image("cluttered", *SIZE, 2 * 4)  # the front view of seed 4
    from scipy.ndimage import binary_dilation

    away = ~binary_dilation(bushy.masks["front"], iterations=2)
    diff = np.abs(bushy.front.astype(int) - wall.astype(int))[away]
    assert diff.max() <= 1


def test_dark_skin_photographs_darker_than_light_skin(bushy, ponytail):
    def skin_grey(pair):
        lab = pair.labels["front"]
        p = pair.fdp.views["front"].points
        y0, y1 = int(p["3.5"][1]) + 10, int(p["2.1"][1]) - 10
        sel = np.zeros(lab.shape, bool)
        sel[y0:y1] = True
        sel &= lab == LABELS["head"]
        return pair.front[sel].mean()

    assert skin_grey(bushy) < 0.6 * skin_grey(ponytail)
