"""recon annotate: where the points start, the session's files, and every API endpoint
(including what it refuses)."""

import importlib.util
import json

import numpy as np
import pytest
from PIL import Image
from starlette.testclient import TestClient

from mpeg4 import FEATURE_POINTS, InputError
from mpeg4.io import FdpFile, ViewAnnotation, read_fdp_json, write_fdp_json
from recon.annotate import AnnotationSession, create_app
from recon.annotate.placement import (GUESS_CONFIDENCE, HEAD_FILL, complete_views, detector, fit_view,
                                      generic_layout, initial_annotation, shown_in)
from recon.annotate.server import MAX_BODY, TOKEN_HEADER

TOKEN = "t0ken-for-tests"
BASE = "http://127.0.0.1:8765"
FRONT_SIZE, SIDE_SIZE = (640, 800), (600, 800)


@pytest.fixture(scope="module")
def layout():
    return generic_layout()


def _photo(path, size, fmt=None, **kw):
    rng = np.random.default_rng(len(str(path)))
    Image.fromarray(rng.integers(0, 255, (size[1], size[0], 3), dtype=np.uint8)).save(path, fmt, **kw)
    return path


@pytest.fixture
def photos(tmp_path):
    return _photo(tmp_path / "front.png", FRONT_SIZE), _photo(tmp_path / "side.jpg", SIDE_SIZE, quality=80)


@pytest.fixture
def session(photos, tmp_path):
    s = AnnotationSession(*photos, tmp_path / "person.fdp.json", detect=False)
    yield s
    s.close()


@pytest.fixture
def client(session):
    return TestClient(create_app(session, TOKEN), base_url=BASE, headers={TOKEN_HEADER: TOKEN})


@pytest.fixture(scope="module")
def idle(tmp_path_factory):
    """One session for the checks that write nothing."""
    folder = tmp_path_factory.mktemp("idle")
    s = AnnotationSession(_photo(folder / "front.png", FRONT_SIZE), _photo(folder / "side.jpg", SIDE_SIZE),
                          folder / "person.fdp.json", detect=False)
    yield s
    assert not s.fdp_path.exists()
    s.close()


def _views(client):
    return client.get("/api/state").json()["views"]


# --- where the points start ------------------------------------------------------------

def _similarity(angle, scale, shift, flip=False):
    c, s = np.cos(angle), np.sin(angle)
    m = scale * np.array([[c, -s], [s, c]]) @ np.diag([-1.0 if flip else 1.0, 1.0])
    return lambda p: np.asarray(p) @ m.T + shift


@pytest.mark.parametrize("flip", [False, True])
def test_fit_view_recovers_a_similarity_from_a_few_points(layout, flip):
    truth = _similarity(0.07, 2300.0, [310.0, 420.0], flip)
    side = {i: layout["side"][i] for i in shown_in("side")}
    known = {i: truth(side[i]) for i in ("9.3", "2.1", "10.5", "11.4")}
    fit = fit_view(side, known, SIDE_SIZE, reflect=True)
    assert fit.known == 4 and fit.rms_px < 1e-6 and fit.scale == pytest.approx(2300.0)
    err = max(np.linalg.norm(fit(side[i])[0] - truth(side[i])) for i in side)
    assert err < 1e-6
    # Without reflection a mirrored photo cannot be matched exactly.
    if flip:
        assert fit_view(side, known, SIDE_SIZE, reflect=False).rms_px > 10


def test_fit_view_with_nothing_known_frames_the_head_in_the_image(layout):
    front = {i: layout["front"][i] for i in shown_in("front")}
    fit = fit_view(front, {}, FRONT_SIZE)
    px = fit(np.array(list(front.values())))
    assert fit.known == 0 and fit.rms_px is None
    assert np.ptp(px[:, 1]) == pytest.approx(HEAD_FILL * FRONT_SIZE[1])
    centre = 0.5 * (px.min(axis=0) + px.max(axis=0))
    assert np.allclose(centre, [(FRONT_SIZE[0] - 1) / 2, (FRONT_SIZE[1] - 1) / 2])
    # One known point: the same framing moved onto it.
    one = fit_view(front, {"9.3": np.array([100.0, 200.0])}, FRONT_SIZE)
    assert np.allclose(one(front["9.3"])[0], [100, 200]) and one.scale == pytest.approx(fit.scale)


def test_complete_views_fills_from_the_known_points_and_borrows_height_across(layout):
    truth = _similarity(0.0, 2000.0, [320.0, 380.0])
    front_ids = shown_in("front")
    known = {i: truth(layout["front"][i]) for i in front_ids[::3]}
    views, report = complete_views({"front": ViewAnnotation(points=known)}, {"front": FRONT_SIZE, "side": FRONT_SIZE},
                                   layout)
    f, s = views["front"], views["side"]
    for i in front_ids:
        assert np.allclose(f.points[i], truth(layout["front"][i]), atol=1e-6)
        assert (i in known) == (i not in f.confidence)  # known points keep no confidence
    assert set(report["front"]["placed"]) == set(front_ids) - set(known)
    assert all(f.confidence[i] == GUESS_CONFIDENCE for i in report["front"]["placed"])
    # The side photo (same size, nothing known) gets the front's scale and heights.
    assert set(s.points) == set(shown_in("side"))
    for i in ("9.3", "2.1", "11.4", "3.7"):
        assert s.points[i][1] == pytest.approx(truth(layout["front"][i])[1], abs=1e-6)
    assert report["side"]["known"] == 0


def test_initial_annotation_uses_a_detector_and_fills_what_it_does_not_give(photos, layout):
    truth = _similarity(0.0, 1800.0, [320.0, 390.0])

    def detect(front, side):
        assert front.endswith("front.png") and side.endswith("side.jpg")
        pts = {i: truth(layout["front"][i]) for i in ("3.5", "3.6", "9.3", "2.1", "8.3", "8.4")}
        return FdpFile(views={"front": ViewAnnotation(points=pts, confidence={i: 0.9 for i in pts}),
                              "side": ViewAnnotation()})

    init = initial_annotation(*photos, detect=detect, layout=layout)
    assert init.source == "landmarks" and "automatic detection" in init.message
    front = init.fdp.views["front"]
    assert front.confidence["3.5"] == 0.9 and front.confidence["4.1"] == GUESS_CONFIDENCE
    assert np.allclose(front.points["4.1"], truth(layout["front"]["4.1"]), atol=1e-6)
    assert (front.width, front.height) == FRONT_SIZE


def test_initial_annotation_survives_a_failing_detector(photos, layout, capsys):
    def detect(front, side):
        raise RuntimeError("model file missing")

    init = initial_annotation(*photos, detect=detect, layout=layout)
    assert init.source == "generic"
    assert "automatic detection failed (RuntimeError: model file missing)" in init.message
    err = capsys.readouterr().err  # one line says why, no traceback
    assert err.strip().splitlines() == ["recon: automatic detection failed (RuntimeError: model file missing); the "
                                        "points start from the generic head"]
    assert set(init.fdp.views["front"].points) == set(shown_in("front"))


def test_a_background_session_serves_its_photos_while_the_points_are_placed(photos, tmp_path):
    import threading
    import time

    gate = threading.Event()

    def slow(front, side):  # a detector that takes its time, then fails
        gate.wait(10)
        raise RuntimeError("no face")

    t0 = time.perf_counter()
    s = AnnotationSession(*photos, tmp_path / "new.fdp.json", detect=slow, background=True)
    assert time.perf_counter() - t0 < 5 and not s._ready.is_set()
    c = TestClient(create_app(s, TOKEN), base_url=BASE, headers={TOKEN_HEADER: TOKEN})
    assert c.get("/api/photo/front").status_code == 200  # served while the detector runs
    got = {}
    asker = threading.Thread(target=lambda: got.update(state=c.get("/api/state").json()))
    asker.start()
    asker.join(0.3)
    assert asker.is_alive()  # the page's first request waits for the points...
    gate.set()
    asker.join(10)
    state = got["state"]  # ... and gets them once placed
    assert state["initialisation"]["source"] == "generic" and "RuntimeError: no face" in state["initialisation"]["message"]
    assert set(state["views"]["front"]["points"]) == set(shown_in("front"))
    s.close()
    # An existing file is read at once, and its errors stop the session there.
    (tmp_path / "bad.fdp.json").write_text("{")
    with pytest.raises(InputError, match="bad.fdp.json"):
        AnnotationSession(*photos, tmp_path / "bad.fdp.json", detect=slow, background=True)


def test_the_landmarks_seam():
    detect, why = detector()
    if importlib.util.find_spec("recon.landmarks") is None:
        assert detect is None and "recon.landmarks" in why
    else:
        assert callable(detect) or why


def test_initial_annotation_prefers_the_users_file_and_checks_its_photo_sizes(photos, tmp_path, layout):
    path = tmp_path / "a.fdp.json"
    nose = {"9.3": np.array([5.0, 6.0])}
    write_fdp_json(path, FdpFile(views={"front": ViewAnnotation("front.png", *FRONT_SIZE, nose)}))
    init = initial_annotation(*photos, path, detect=lambda f, s: pytest.fail("a saved file comes first"), layout=layout)
    assert init.source == "file" and list(init.fdp.views["front"].points) == ["9.3"]
    side = init.fdp.views["side"]
    assert side.points == {} and (side.width, side.height) == SIDE_SIZE
    write_fdp_json(path, FdpFile(views={"front": ViewAnnotation("front.png", 100, 100, {})}))
    with pytest.raises(InputError, match=r"front annotations were made on a 100x100 image but .*front.png is 640x800"):
        initial_annotation(*photos, path, layout=layout)


# --- the page and its files ----------------------------------------------------------

def test_page_and_static_files_are_served_with_a_strict_policy(client):
    r = client.get("/", headers={TOKEN_HEADER: ""})
    assert r.status_code == 200 and "recon annotate" in r.text
    assert "default-src 'self'" in r.headers["content-security-policy"]
    js = client.get("/static/js/main.js")
    assert js.status_code == 200 and "javascript" in js.headers["content-type"]


def test_state_describes_photos_points_and_catalogue(client, session):
    s = client.get("/api/state").json()
    assert s["photos"]["front"] == {"name": "front.png", "width": 640, "height": 800, "note": None}
    assert s["initialisation"]["source"] == "generic"
    assert "(front: the image centre and size; side: the image centre and size)" in s["initialisation"]["message"]
    assert len(s["catalogue"]) == 84 and s["catalogue"][0]["description"] == FEATURE_POINTS["2.1"].description
    assert set(s["views"]["front"]["points"]) == set(shown_in("front"))
    assert all(c == GUESS_CONFIDENCE for c in s["views"]["side"]["confidence"].values())
    assert s["colours"]["3"].startswith("#") and s["file"]["exists"] is False
    assert s["file"]["path"] == str(session.fdp_path)


def test_photos_are_served_as_stored(client, photos):
    front, side = photos
    r = client.get("/api/photo/front")
    assert r.status_code == 200 and r.headers["content-type"] == "image/png" and r.content == front.read_bytes()
    r = client.get("/api/photo/side")
    assert r.headers["content-type"] == "image/jpeg" and r.content == side.read_bytes()


def test_a_rotated_photo_is_served_upright_as_recon_reads_it(tmp_path):
    from recon.photos import read_photo

    exif = Image.Exif()
    exif[0x0112] = 6  # stored sideways: turn 90 degrees clockwise to view
    front = _photo(tmp_path / "f.jpg", (320, 240), exif=exif.tobytes())
    side = _photo(tmp_path / "s.png", (300, 400))
    s = AnnotationSession(front, side, tmp_path / "a.fdp.json", detect=False)
    c = TestClient(create_app(s, TOKEN), base_url=BASE, headers={TOKEN_HEADER: TOKEN})
    state = c.get("/api/state").json()
    assert "EXIF orientation tag (6)" in state["photos"]["front"]["note"]
    assert (state["photos"]["front"]["width"], state["photos"]["front"]["height"]) == (240, 320)
    assert max(p[0] for p in state["views"]["front"]["points"].values()) < 240  # placed on the upright photo
    r = c.get("/api/photo/front")
    assert r.headers["content-type"] == "image/png"
    import io

    served = np.asarray(Image.open(io.BytesIO(r.content)))
    assert served.shape == (320, 240, 3)
    assert np.array_equal(served, read_photo(front))
    stored = np.asarray(Image.open(front).convert("RGB"))
    assert np.array_equal(served, np.rot90(stored, -1))
    s.close()


def test_save_writes_a_valid_file_and_keeps_a_backup_of_the_previous_one(client, session):
    views = _views(client)
    views["front"]["points"]["9.3"] = [300.25, 410.5]
    del views["front"]["confidence"]["9.3"]
    r = client.put("/api/fdp", json={"views": views})
    assert r.status_code == 200, r.text
    assert r.json()["backup"] is None  # nothing was there before
    saved = read_fdp_json(session.fdp_path)
    assert np.allclose(saved.views["front"].points["9.3"], [300.25, 410.5])
    assert "9.3" not in saved.views["front"].confidence and saved.views["front"].confidence["3.5"] == 0
    assert saved.views["front"].image == "front.png" and saved.views["side"].image == "side.jpg"
    assert (saved.views["side"].width, saved.views["side"].height) == SIDE_SIZE
    assert saved.metadata["annotate"]["initialised_from"] == "generic"
    assert client.get("/api/fdp").json()["views"]["front"]["points"]["9.3"] == [300.25, 410.5]

    # A new session on the same file starts from it and backs it up before its first save.
    first = session.fdp_path.read_bytes()
    again = AnnotationSession(session.photos["front"].path, session.photos["side"].path, session.fdp_path,
                              detect=lambda f, s: pytest.fail("the saved file comes first"))
    c2 = TestClient(create_app(again, TOKEN), base_url=BASE, headers={TOKEN_HEADER: TOKEN})
    assert c2.get("/api/state").json()["initialisation"]["source"] == "file"
    views["front"]["points"]["9.3"] = [301.0, 411.0]
    r = c2.put("/api/fdp", json={"views": views})
    assert r.json()["backup"] == str(again.backup_path)
    assert again.backup_path.read_bytes() == first
    views["front"]["points"]["9.3"] = [302.0, 412.0]
    assert c2.put("/api/fdp", json={"views": views}).json()["backup"] is None
    assert again.backup_path.read_bytes() == first  # the backup is the file before the session
    assert read_fdp_json(session.fdp_path).views["front"].points["9.3"].tolist() == [302.0, 412.0]
    again.close()


def test_save_keeps_what_the_file_holds_besides_the_points(photos, tmp_path):
    path = tmp_path / "head.fdp.json"
    nose = {"9.3": np.array([5.0, 6.0])}
    write_fdp_json(path, FdpFile(views={"front": ViewAnnotation("front.png", *FRONT_SIZE, nose)},
                                 points3d={"9.3": np.array([0.0, 0.01, 0.1])}, metadata={"source": "recon fit"}))
    s = AnnotationSession(*photos, path, detect=False)
    c = TestClient(create_app(s, TOKEN), base_url=BASE, headers={TOKEN_HEADER: TOKEN})
    views = _views(c)
    views["front"]["points"]["9.3"] = [7.0, 8.0]
    assert c.put("/api/fdp", json={"views": views}).status_code == 200
    saved = read_fdp_json(path)
    assert saved.points3d["9.3"].tolist() == [0.0, 0.01, 0.1] and saved.metadata["source"] == "recon fit"
    s.close()


def test_a_file_changed_on_disk_is_not_overwritten_unless_asked(client, session):
    views = _views(client)
    assert client.put("/api/fdp", json={"views": views}).status_code == 200
    # The session's own file is replaced without a backup: it is all in the page's history.
    assert client.put("/api/fdp", json={"views": views}).json()["backup"] is None
    assert not session.backup_path.exists()
    session.fdp_path.write_text(session.fdp_path.read_text() + " ")
    edited = session.fdp_path.read_bytes()
    r = client.put("/api/fdp", json={"views": views})
    assert r.status_code == 409 and "changed on disk" in r.json()["error"]
    assert session.fdp_path.read_bytes() == edited
    # Overwriting on the user's say-so keeps the other version in the backup.
    r = client.put("/api/fdp", json={"views": views, "force": True})
    assert r.status_code == 200 and session.backup_path.read_bytes() == edited
    # Loading someone else's version makes it the base, and the next save backs it up.
    session.fdp_path.write_bytes(session.fdp_path.read_bytes() + b"\n")
    other = session.fdp_path.read_bytes()
    assert client.get("/api/fdp").status_code == 200
    assert client.put("/api/fdp", json={"views": views}).json()["backup"] == str(session.backup_path)
    assert session.backup_path.read_bytes() == other


@pytest.mark.parametrize("change, status, needle", [
    (lambda v: v["front"]["points"].update({"12.1": [1, 2]}), 422, "unknown feature point '12.1'"),
    (lambda v: v["front"]["points"].update({"9.3": [900, 2]}), 422, "lies outside the 640x800 image"),
    (lambda v: v["front"]["points"].update({"9.3": [1, "x"]}), 422,
     'views.front.points["9.3"]: expected [x, y] numbers'),
    (lambda v: v["front"]["confidence"].update({"9.3": 2}), 422, "2 is greater than the maximum of 1"),
    (lambda v: v["front"]["points"].update({"3.5": v["front"]["points"]["3.6"],
                                            "3.6": v["front"]["points"]["3.5"]}), 422, "3.5/3.6"),
    (lambda v: v.update({"back": {"points": {}}}), 422, "expected an object with 'front' and 'side'"),
    (lambda v: v["side"].update({"image": "/etc/passwd"}), 422, "send only points and confidence"),
])
def test_invalid_points_are_refused_and_nothing_is_written(client, session, change, status, needle):
    views = _views(client)
    assert client.put("/api/fdp", json={"views": views}).status_code == 200
    before = session.fdp_path.read_bytes()
    change(views)
    for path, method in (("/api/fdp", "PUT"), ("/api/complete", "POST"), ("/api/fit", "POST")):
        r = client.request(method, path, json={"views": views})
        assert r.status_code == status, (path, r.text)
        assert needle in r.json()["error"], r.json()
    assert session.fdp_path.read_bytes() == before


@pytest.mark.parametrize("method, path", [("PUT", "/api/fdp"), ("POST", "/api/complete"), ("POST", "/api/fit")])
def test_malformed_json_is_refused(client, method, path):
    r = client.request(method, path, content=b'{"views": {"front": ', headers={"content-type": "application/json"})
    assert r.status_code == 400 and r.json()["error"].startswith("malformed JSON")
    for body in (b"[1, 2]", b'{"points": {}}', b'{"views": {}, "extra": 1}'):
        r = client.request(method, path, content=body)
        assert r.status_code == 422 and "expected a JSON object with 'views'" in r.json()["error"]


def test_complete_puts_removed_points_back(client):
    views = _views(client)
    removed = {i: views["front"]["points"].pop(i) for i in ("4.1", "8.3", "11.2")}
    removed_side = views["side"]["points"].pop("10.5")
    for i in removed:
        views["front"]["confidence"].pop(i)
    views["side"]["confidence"].pop("10.5")
    r = client.post("/api/complete", json={"views": views}).json()
    assert sorted(r["placed"]["front"]) == sorted(removed) and r["placed"]["side"] == ["10.5"]
    for i, p in removed.items():
        assert np.allclose(r["views"]["front"]["points"][i], p, atol=1e-6)
    assert np.allclose(r["views"]["side"]["points"]["10.5"], removed_side, atol=1e-6)


def test_guesses_follow_the_points_placed_by_hand(client, layout):
    # A person larger in the photo and turned a little: five points dragged into place...
    views = _views(client)
    fit = fit_view({i: layout["front"][i] for i in shown_in("front")}, {}, FRONT_SIZE)
    truth = _similarity(0.05, 1.3 * fit.scale, [300.0, 420.0])
    for i in ("3.5", "3.6", "9.3", "2.1", "8.3"):
        views["front"]["points"][i] = truth(layout["front"][i]).tolist()
        del views["front"]["confidence"][i]
    views["front"]["points"]["9.3"][0] += 2.0  # a hand is not exact
    r = client.post("/api/complete", json={"views": views, "replace_guesses": True}).json()
    assert r["how"] == {"front": "fitted to 5 points", "side": "the front photo's scale and height"}
    front = r["views"]["front"]
    assert set(front["points"]) == set(shown_in("front")) and len(r["placed"]["front"]) == len(front["points"]) - 5
    assert front["points"]["9.3"] == views["front"]["points"]["9.3"]  # hand-placed points stay
    # ... bring the guesses with them (within the hand's 2 px, spread by the fit).
    err = [np.linalg.norm(np.array(front["points"][i]) - truth(layout["front"][i])) for i in r["placed"]["front"]]
    assert max(err) < 2.0
    assert all(front["confidence"][i] == GUESS_CONFIDENCE for i in r["placed"]["front"])
    # The side photo, with nothing placed by hand, follows the front's scale (same height in pixels).
    side = r["views"]["side"]["points"]
    span = np.ptp([layout["side"][i][1] for i in side])
    scale = SIDE_SIZE[1] / FRONT_SIZE[1] * 1.3 * fit.scale
    assert np.ptp([p[1] for p in side.values()]) == pytest.approx(scale * span, rel=0.01)
    # Without the flag only missing points are placed.
    r = client.post("/api/complete", json={"views": views}).json()
    assert r["placed"] == {"front": [], "side": []}


def test_fit_serves_a_valid_head(client, validate_gltf, tmp_path):
    assert client.get("/api/head.glb").status_code == 404
    r = client.post("/api/fit", json={"views": _views(client)})
    assert r.status_code == 200, r.text
    fit = r.json()
    assert fit["glb"].startswith("/api/head.glb") and len(fit["points3d"]) == 84
    # The generic head's own points, projected and fitted back: the same head (ipd 63 mm vs its own).
    head = client.get(fit["glb"])
    assert head.headers["content-type"] == "model/gltf-binary" and len(head.content) == fit["bytes"]
    (tmp_path / "preview.glb").write_bytes(head.content)
    assert validate_gltf(tmp_path / "preview.glb")["issues"]["numErrors"] == 0
    assert max(abs(d) for d in fit["height_residual_mm"].values()) < 1.0


def test_heights_that_disagree_still_give_a_preview_with_the_refusal(client):
    views = _views(client)
    assert client.post("/api/fit", json={"views": views}).json()["warning"] is None
    # The side photo's hairline 60 px lower than the front photo's (about 18 mm).
    p = views["side"]["points"]["11.1"]
    views["side"]["points"]["11.1"] = [p[0], p[1] + 60]
    fit = client.post("/api/fit", json={"views": views}).json()
    assert "heights of the points marked in both photos disagree: 11.1" in fit["warning"]
    assert "--focal" in fit["warning"] and abs(fit["height_residual_mm"]["11.1"]) > 8.0
    # The build keeps its check.
    from mpeg4.io.fdp_json import parse_fdp
    from recon.shape.fit import fit_head

    with pytest.raises(InputError, match="disagree: 11.1"):
        fit_head(parse_fdp({"format": "mpeg4-fdp", "version": 1, "views": views}), where="x")


def test_the_preview_fit_uses_the_given_camera_and_size(photos, tmp_path):
    s = AnnotationSession(*photos, tmp_path / "a.fdp.json", detect=False, ipd_mm=58.0, focal_px=4000.0)
    c = TestClient(create_app(s, TOKEN), base_url=BASE, headers={TOKEN_HEADER: TOKEN})
    fit = c.post("/api/fit", json={"views": _views(c)}).json()
    assert fit["assumptions"]["ipd_mm"] == 58.0 and fit["assumptions"]["camera"] == "perspective, focal length 4000 px"
    ipd = np.linalg.norm(np.subtract(fit["points3d"]["3.5"], fit["points3d"]["3.6"]))
    assert ipd == pytest.approx(0.058, abs=0.001)  # the pupils sit on the rigidly moved eyeballs
    s.close()


def test_fit_errors_name_the_missing_points(client):
    views = _views(client)
    for i in ("3.5", "3.6"):
        views["front"]["points"].pop(i)
        views["front"]["confidence"].pop(i)
    r = client.post("/api/fit", json={"views": views})
    assert r.status_code == 422 and "pupils 3.5 and 3.6 are not marked" in r.json()["error"]


# --- refusals ------------------------------------------------------------------------

ENDPOINTS = [("GET", "/api/state"), ("GET", "/api/photo/front"), ("GET", "/api/photo/side"), ("GET", "/api/fdp"),
             ("PUT", "/api/fdp"), ("POST", "/api/complete"), ("POST", "/api/fit"), ("GET", "/api/head.glb")]


@pytest.mark.parametrize("method, path", ENDPOINTS)
@pytest.mark.parametrize("token", [None, "", "wrong", TOKEN + "x"])
def test_every_api_call_needs_the_token(idle, method, path, token):
    c = TestClient(create_app(idle, TOKEN), base_url=BASE)
    headers = {} if token is None else {TOKEN_HEADER: token}
    r = c.request(method, path, headers=headers, json={"views": {}} if method != "GET" else None)
    assert r.status_code == 401 and "token" in r.json()["error"]
    assert c.request(method, path + "?token=" + TOKEN).status_code == 401  # not in the query either


@pytest.mark.parametrize("host", ["evil.example:8765", "evil.example", "127.0.0.1.evil.example", "192.168.1.5:8765",
                                  ""])
def test_a_foreign_host_header_is_refused(idle, host):
    client = TestClient(create_app(idle, TOKEN), base_url=BASE, headers={TOKEN_HEADER: TOKEN})
    for path in ("/", "/api/state", "/static/js/main.js"):
        r = client.get(path, headers={"host": host})
        assert r.status_code == 400, (path, host)
    assert client.get("/api/state", headers={"host": "localhost:8765"}).status_code == 200


def test_a_state_change_from_another_origin_is_refused(client):
    views = _views(client)
    r = client.put("/api/fdp", json={"views": views}, headers={"origin": "http://evil.example"})
    assert r.status_code == 403
    assert client.put("/api/fdp", json={"views": views}, headers={"origin": BASE}).status_code == 200


@pytest.mark.parametrize("path", ["/api/photo/../../../../etc/passwd", "/api/photo/%2e%2e%2f%2e%2e%2fetc%2fpasswd",
                                  "/api/photo/front/../../session.py", "/api/photo/person.fdp.json",
                                  "/api/photo/..%2fperson.fdp.json", "/api/photo/", "/api/photo/back",
                                  "/static/../session.py", "/static/%2e%2e/session.py", "/static/..%2fserver.py",
                                  "/static/js/../../../annotate/server.py", "/api/file?path=/etc/passwd",
                                  "/person.fdp.json", "/front.png", "/api/fdp/../photo/front%00"])
def test_nothing_outside_the_allowed_files_is_served(idle, path):
    client = TestClient(create_app(idle, TOKEN), base_url=BASE, headers={TOKEN_HEADER: TOKEN})
    r = client.get(path)
    assert r.status_code == 404, (path, r.status_code)
    assert b"root:" not in r.content and b"def create_app" not in r.content and b"Starlette" not in r.content


def _raw_get(app, raw: bytes):
    """Send a request path exactly as given (test clients tidy '..' away before sending)."""
    import asyncio
    from urllib.parse import unquote

    path, _, query = raw.partition(b"?")
    scope = {"type": "http", "asgi": {"version": "3.0"}, "http_version": "1.1", "method": "GET", "scheme": "http",
             "path": unquote(path.decode("latin-1")), "raw_path": path, "query_string": query, "root_path": "",
             "headers": [(b"host", b"127.0.0.1:8765"), (TOKEN_HEADER.encode(), TOKEN.encode())],
             "client": ("127.0.0.1", 50000), "server": ("127.0.0.1", 8765)}
    sent = []

    async def run():
        done = asyncio.Event()
        asked = False

        async def receive():
            nonlocal asked
            if not asked:
                asked = True
                return {"type": "http.request", "body": b"", "more_body": False}
            await done.wait()
            return {"type": "http.disconnect"}

        async def send(message):
            sent.append(message)
            if message["type"] == "http.response.body" and not message.get("more_body"):
                done.set()

        await app(scope, receive, send)

    asyncio.run(asyncio.wait_for(run(), 10))
    status = next(m["status"] for m in sent if m["type"] == "http.response.start")
    return status, b"".join(m.get("body", b"") for m in sent if m["type"] == "http.response.body")


@pytest.mark.parametrize("raw", [b"/static/../server.py", b"/static/../../recon/annotate/server.py",
                                 b"/static/%2e%2e/server.py", b"/static/js/../../session.py",
                                 b"/static/..%2f..%2f..%2f..%2f..%2fetc/passwd", b"/api/photo/../../etc/passwd",
                                 b"/api/photo/%2e%2e%2f%2e%2e%2fetc%2fpasswd", b"/static//etc/passwd",
                                 b"/static/%2fetc%2fpasswd"])
def test_raw_paths_cannot_climb_out(idle, raw):
    status, body = _raw_get(create_app(idle, TOKEN), raw)
    assert status == 404, (raw, status)
    assert b"root:" not in body and b"def create_app" not in body and b"import" not in body


def test_oversized_bodies_are_refused(client, session):
    big = b'{"views": {"front": {"points": {}}}, "pad": "' + b"x" * MAX_BODY + b'"}'
    for method, path in (("PUT", "/api/fdp"), ("POST", "/api/complete"), ("POST", "/api/fit")):
        r = client.request(method, path, content=big, headers={"content-type": "application/json"})
        assert r.status_code == 413, r.text

        # Without a length up front (chunked), counted as it arrives.
        def chunks():
            for _ in range(MAX_BODY // 65536 + 2):
                yield b"x" * 65536

        r = client.request(method, path, content=chunks())
        assert r.status_code == 413
    assert not session.fdp_path.exists()


def test_cli_help_lists_annotate():
    from typer.testing import CliRunner

    from recon.cli import app

    out = CliRunner().invoke(app, ["annotate", "--help"])
    assert out.exit_code == 0 and "--no-browser" in out.output and "--fdp" in out.output


def test_default_annotation_file_is_beside_the_front_photo(photos):
    s = AnnotationSession(*photos, detect=False)
    assert s.fdp_path == photos[0].with_name("front.fdp.json")
    s.close()
    assert json.loads(json.dumps(s.state()))["file"]["name"] == "front.fdp.json"
