"""Synthetic photo pairs: true pixels, determinism, and the committed example."""

import json

import numpy as np
import pytest

from recon.example import EXAMPLE_DIR, EXAMPLE_FDP


@pytest.fixture(scope="module")
def pair(ict_npz):
    from recon.evaluate.synthetic import load_ict, synthetic_pair

    return synthetic_pair(7, size=(400, 500), data=load_ict(ict_npz), texture_size=256)


def test_points_are_where_the_camera_puts_the_head_s_feature_points(pair):
    head = pair.person.head
    for view in ("front", "side"):
        pts = pair.fdp.views[view].points
        assert len(pts) > 30
        for i, p in pts.items():
            np.testing.assert_allclose(p, pair.cameras[view].project(head.fp_position(i)[None])[0], atol=1e-9)
    # The side photo shows the face's left: no right-side labels, the nose towards the image's left.
    from mpeg4.catalogue import FEATURE_POINTS

    assert {FEATURE_POINTS[i].side for i in pair.fdp.views["side"].points} == {"C", "L"}
    side = pair.fdp.views["side"].points
    assert side["9.3"][0] < side["10.3"][0]
    # The head is in the photo and the backdrop around it.
    assert 0.15 < pair.masks["front"].mean() < 0.6
    assert pair.masks["front"][0].sum() == 0


def test_same_seed_same_photos(pair, ict_npz):
    from recon.evaluate.synthetic import load_ict, synthetic_pair

    again = synthetic_pair(7, size=(400, 500), data=load_ict(ict_npz), texture_size=256)
    assert np.array_equal(again.front, pair.front) and np.array_equal(again.side, pair.side)
    other = synthetic_pair(8, size=(400, 500), data=load_ict(ict_npz), texture_size=256)
    assert np.abs(other.front.astype(int) - pair.front.astype(int)).mean() > 3


@pytest.mark.slow
def test_committed_example_is_what_the_script_makes(ict_npz, tmp_path):
    import importlib.util

    from PIL import Image

    spec = importlib.util.spec_from_file_location("make_example_photos",
                                                  EXAMPLE_DIR.parents[1] / "scripts" / "make_example_photos.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    paths = mod.make_example(tmp_path, ict_npz)
    for name in ("front", "side"):
        a = np.asarray(Image.open(paths[name])).astype(float)
        b = np.asarray(Image.open(EXAMPLE_DIR / f"{name}.jpg")).astype(float)
        # Renders may differ by a grey level between OpenGL drivers; the JPEGs then too.
        assert a.shape == b.shape and np.abs(a - b).mean() < 1.0
    new = json.loads(paths["fdp"].read_text())["views"]
    old = json.loads(EXAMPLE_FDP.read_text())["views"]
    for view in ("front", "side"):
        assert new[view]["points"].keys() == old[view]["points"].keys()
        for i in old[view]["points"]:
            np.testing.assert_allclose(new[view]["points"][i], old[view]["points"][i], atol=1e-6)
