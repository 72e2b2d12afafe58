"""recon annotate turns a profile read backwards round at once: the side photo's points placed
again for the other facing (detected again, or mirrored), and a facing too unsure for
recon build still gives the page detected points, flagged for checking."""

import dataclasses
import importlib.util

import numpy as np
import pytest
from PIL import Image
from starlette.testclient import TestClient

from mpeg4 import FEATURE_POINTS
from recon.annotate import AnnotationSession, create_app
from recon.annotate.server import TOKEN_HEADER
from recon.annotate.turn import mirrored_side, side_facing
from recon.example import EXAMPLE_DIR

TOKEN = "t0ken-for-tests"
HAS_MEDIAPIPE = importlib.util.find_spec("mediapipe") is not None


def _photo(path, size):
    rng = np.random.default_rng(len(str(path)))
    Image.fromarray(rng.integers(0, 255, (size[1], size[0], 3), dtype=np.uint8)).save(path)
    return path


def _ear_and_nose(side: dict) -> tuple[float, float]:
    ear = np.mean([p[0] for i, p in side.items() if i.startswith("10.")])
    return float(side["9.3"][0]), float(ear)


@pytest.fixture
def blank(tmp_path):
    """A session on two noise pictures: the points come from the generic head, facing left."""
    s = AnnotationSession(_photo(tmp_path / "front.png", (640, 800)), _photo(tmp_path / "side.png", (600, 800)),
                          tmp_path / "p.fdp.json", detect=False)
    yield s
    s.close()


def test_mirroring_swaps_each_point_for_its_partner_and_twice_gives_them_back(blank):
    side = blank.views["side"]
    assert side_facing(side) == "left"
    turned = mirrored_side(side)
    assert side_facing(turned) == "right"
    for i, p in side.points.items():
        j = FEATURE_POINTS[i].mirror or i
        assert j in turned.points and turned.points[j][1] == pytest.approx(p[1])
    nose, ear = _ear_and_nose(side.points)
    t_nose, t_ear = _ear_and_nose(turned.points)
    assert nose < ear and t_nose > t_ear  # the nose now points right
    back = mirrored_side(turned)
    assert set(back.points) == set(side.points)
    for i, p in side.points.items():
        assert np.allclose(back.points[i], p, atol=1e-9)


def test_the_turn_endpoint_mirrors_without_detection_and_leaves_the_front_alone(blank):
    client = TestClient(create_app(blank, TOKEN), base_url="http://127.0.0.1:8765", headers={TOKEN_HEADER: TOKEN})
    views = client.get("/api/state").json()["views"]
    r = client.post("/api/turn", json={"views": views})
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["facing"] == "right" and body["was"] == "left" and "mirrored" in body["how"]
    assert body["views"]["front"] == views["front"]
    side = {i: np.array(p) for i, p in body["views"]["side"]["points"].items()}
    nose, ear = _ear_and_nose(side)
    assert nose > ear
    assert body["side_facing"] == {"facing": "right", "turned": True, "given": True}
    assert client.get("/api/state").json()["side_facing"]["turned"] is True


@pytest.mark.skipif(not HAS_MEDIAPIPE, reason="mediapipe is not installed")
def test_turning_detects_again_for_the_other_facing_and_back(tmp_path):
    s = AnnotationSession(EXAMPLE_DIR / "front.jpg", EXAMPLE_DIR / "side.jpg", tmp_path / "e.fdp.json")
    try:
        read = s.side_facing
        assert read["facing"] == "left" and read["confidence"] >= 0.5 and not read["given"]
        views = s.views_json(s.views)
        turned = s.turn(views)
        assert turned["facing"] == "right" and turned["how"].startswith("detected again")
        side = {i: np.array(p) for i, p in turned["views"]["side"]["points"].items()}
        nose, ear = _ear_and_nose(side)
        assert nose > ear
        # Read backwards on purpose, the points fit the photo worse: the nose tip lands off
        # the face's outline, on the back of the head, far from where it was.
        assert abs(side["9.3"][0] - views["side"]["points"]["9.3"][0]) > 100
        again = s.turn(turned["views"])
        assert again["facing"] == "left"
        for i, p in views["side"]["points"].items():
            assert np.allclose(again["views"]["side"]["points"][i], p, atol=0.5), i
    finally:
        s.close()


@pytest.mark.skipif(not HAS_MEDIAPIPE, reason="mediapipe is not installed")
def test_an_unsure_facing_still_gives_detected_points_flagged_for_checking(tmp_path, monkeypatch):
    from recon.evaluate.ict import default_ict_path

    if not default_ict_path().exists():
        pytest.skip(f"needs the ICT FaceKit at {default_ict_path()}")
    from recon.annotate.placement import initial_annotation
    from recon.evaluate.synthetic import hard_pair
    from recon.landmarks import detect, facing
    from recon.landmarks.facing import SURE, UnsureFacing

    # A dressed person whose profile the cues disagree on (hair, a textured background):
    # its confidence lies near SURE (0.20 or 0.26 as a few pixels of the render change), so
    # it is held under SURE here; what is tested is what follows an unsure facing.
    found_facing = facing.profile_facing

    def disagreeing(*args, **kwargs):
        found = found_facing(*args, **kwargs)
        return found if found.given else dataclasses.replace(found, confidence=min(found.confidence, SURE / 2))

    monkeypatch.setattr(facing, "profile_facing", disagreeing)
    pair = hard_pair(3)
    front, side = tmp_path / "front.png", tmp_path / "side.png"
    Image.fromarray(pair.front).save(front)
    Image.fromarray(pair.side).save(side)
    with pytest.raises(UnsureFacing) as refused:
        detect(front, side)  # what recon build does with it: refuse, naming --side-facing
    assert "--side-facing" in str(refused.value)
    init = initial_annotation(front, side)
    assert init.source == "landmarks"
    meta = init.fdp.metadata["landmarks"]
    assert meta["side_facing"]["unsure"] and meta["side_facing"]["facing"] == refused.value.found.facing
    assert any("unsure" in w and "(T)" in w for w in meta["warnings"])
    assert len(init.fdp.views["side"].points) > 20
