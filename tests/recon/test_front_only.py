"""A head from a front photo alone: the identity model, its fit, the build and its errors."""

import json

import numpy as np
import pytest

from mpeg4 import InputError
from mpeg4.generic_head import load_generic_head
from mpeg4.io import read_fdp_json, write_fdp_json
from recon.build import run_build
from recon.example import EXAMPLE_DIR, EXAMPLE_FDP, example_camera
from recon.shape.from_front import fit_front
from recon.shape.identity import build_identity_model, load_identity_model

CAM = example_camera()
FACE = slice(0, 9409)  # ICT "Full face area" (the skin's first vertices)


@pytest.fixture(scope="module")
def generic():
    return load_generic_head()


@pytest.fixture(scope="module")
def ict(ict_npz):
    with np.load(ict_npz) as d:
        return {k: d[k] for k in ("vertices", "identity_deltas")}


def test_shipped_model_is_the_first_50_ict_modes(generic, ict):
    shipped = load_identity_model()
    fresh = build_identity_model(ict["identity_deltas"][:50], generic)
    assert shipped.n_modes == 50 and shipped.n_vertices == sum(p.n_vertices for p in generic.parts.values())
    for name, m in fresh.modes.items():
        # int8 with one scale per mode: half a step at most (0.053 mm for the widest mode).
        step = np.abs(np.concatenate([x for x in fresh.modes.values()], axis=1)).max(axis=(1, 2)) / 127
        assert (np.abs(shipped.modes[name] - m).max(axis=(1, 2)) <= 0.5 * step + 1e-12).all(), name


def _identity(generic, ict, seed):
    from recon.evaluate.ict import identity_head

    return identity_head(ict, seed, generic)  # all 100 modes: half of the face is outside the model


def _front_pixels(head, scale=3000.0, size=1024):
    from mpeg4.catalogue import FEATURE_POINTS

    c = (size - 1) / 2
    return {i: np.array([c + p[0] * scale, c - p[1] * scale]) for i, p in head.fp_positions().items()
            if FEATURE_POINTS[i].front != "N"}


def test_front_only_shape_beats_the_generic_head_on_identities_outside_the_model(generic, ict):
    from recon.shape.deform import deform_head, fit_similarity

    errs, base = [], []
    for seed in (1000, 1001, 1002):
        truth = _identity(generic, ict, seed)
        tfp = truth.fp_positions()
        px = _front_pixels(truth)
        ipd = np.linalg.norm(tfp["3.5"] - tfp["3.6"]) * 1000
        ff = fit_front(px, 1024, 1024, generic, ipd_mm=ipd, estimate_focal=False)
        assert ff.focal_from == "orthographic" and ff.rms_px < 15
        assert sum(s == "front" for s in ff.source.values()) == len([i for i in px if i in generic.feature_points])
        head = deform_head(ff.head, ff.points)
        ids = list(px)

        def error(v, h):
            off = np.mean([h.fp_position(i) - tfp[i] for i in ids], axis=0)
            return np.linalg.norm(v - off - truth.skin.vertices, axis=1)[FACE] * 1000

        errs.append(error(head.skin.vertices, head))
        sim = fit_similarity(np.array([generic.fp_position(i) for i in ids]), np.array([tfp[i] for i in ids]))
        placed = generic.with_vertices({"skin": sim(generic.skin.vertices)})
        base.append(error(placed.skin.vertices, placed))
        # The size comes from the pupils (the eyes then follow rigidly, within a millimetre or two).
        assert np.linalg.norm(ff.points["3.5"] - ff.points["3.6"]) * 1000 == pytest.approx(ipd, abs=1e-6)
        got = head.fp_positions()
        assert np.linalg.norm(got["3.5"] - got["3.6"]) * 1000 == pytest.approx(ipd, abs=2.0)
    front, generic_err = np.median(np.concatenate(errs)), np.median(np.concatenate(base))
    assert front <= 2.0, front  # measured 1.4-1.5 mm
    assert generic_err - front >= 1.0, (front, generic_err)  # measured 3.0 against 1.5


def test_focal_length_is_chosen_among_candidates_and_reported(generic):
    """A close pinhole photo of the generic head: the fit prefers a close camera to an
    orthographic one, and says the focal length was estimated."""
    from mpeg4.camera import Camera

    from recon.photos import FILM_DIAGONAL_MM

    f = 35 / FILM_DIAGONAL_MM * np.hypot(1024, 1024)  # 35 mm equivalent
    pts = generic.fp_positions()
    cam = Camera.fit(np.array(list(pts.values())), 1024, 1024, focal_px=f, margin=0.25)
    px = {i: cam.project(p[None])[0] for i, p in _front_pixels(generic).items() if i in pts
          for p in [pts[i]]}
    ff = fit_front(px, 1024, 1024, generic)
    assert ff.focal_from == "estimated" and ff.focal_px is not None
    assert ff.candidates["orthographic"] > ff.cost + 10  # well above noise: exact pixels
    assert 24 <= ff.focal_px * FILM_DIAGONAL_MM / np.hypot(1024, 1024) <= 50



def test_focal_length_is_chosen_on_the_points_kept_not_on_stray_ones(generic):
    """A distant (135 mm) photo whose ear and hairline points went astray by 0.4 IPD: the
    cameras are compared again once the strays are left out, so the choice is the face's
    (with the strays in, a 50 mm camera explained them best and won)."""
    from mpeg4.camera import Camera
    from mpeg4.catalogue import FEATURE_POINTS

    from recon.photos import FILM_DIAGONAL_MM

    diag = np.hypot(1024, 1024)
    pts = generic.fp_positions()
    ids = [i for i in pts if FEATURE_POINTS[i].front != "N"]
    cam = Camera.fit(np.array([pts[i] for i in ids]), 1024, 1024, focal_px=135 / FILM_DIAGONAL_MM * diag, margin=0.25)
    px = {i: cam.project(pts[i][None])[0] for i in ids}
    ipd = np.linalg.norm(px["3.5"] - px["3.6"])
    rng = np.random.default_rng(0)
    for i in ("11.3", "10.9", "10.6", "11.5"):
        px[i] = px[i] + rng.normal(0, 0.4 * ipd, 2)
    ff = fit_front(px, 1024, 1024, generic, drop_outliers=True)
    assert {"10.6", "10.9", "11.5"} <= set(ff.dropped)
    assert ff.focal_from == "estimated" and ff.focal_px * FILM_DIAGONAL_MM / diag >= 85
    # Every camera's cost is over the same kept points: the 50 mm one is well behind.
    assert ff.candidates["50"] > ff.cost + 5

def _front_only_fdp(tmp_path):
    fdp = read_fdp_json(EXAMPLE_FDP)
    fdp.views = {"front": fdp.views["front"]}
    fdp.views["front"].image = str(EXAMPLE_DIR / "front.jpg")
    path = tmp_path / "front.fdp.json"
    write_fdp_json(path, fdp)
    return path


@pytest.fixture(scope="module")
def front_bundle(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("front_only")
    result = []
    paths = run_build(None, None, _front_only_fdp(tmp), tmp / "out", ipd_mm=CAM["ipd_mm"], texture_size=512,
                      result=result)
    return paths, result[0]


def test_front_only_build_writes_a_valid_bundle_that_says_the_depth_is_estimated(front_bundle, validate_gltf):
    paths, res = front_bundle
    for key in ("head", "obj", "mtl", "texture", "fdp", "preview"):
        assert paths[key].exists(), key
    report = validate_gltf(paths["head"])
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0, report["issues"]
    meta = json.loads(paths["fdp"].read_text())["metadata"]
    assert "estimated" in meta["fit"]["depth"]
    assert meta["provenance"]["options"]["photos"].startswith("front only")
    assert meta["provenance"]["options"]["focal_from"] in ("exif", "estimated", "orthographic")
    fdp = read_fdp_json(paths["fdp"])
    assert len(fdp.points3d) == 84
    uv = np.array(list(fdp.texcoords.values()))
    assert ((uv > 0) & (uv < 1)).all()


def test_front_only_texture_sides_are_smooth_skin_not_streaks(front_bundle):
    """The sides come from the skin model: no photo stretched at a grazing angle, so the
    side layers vary slowly down the head and hardly at all across it."""
    _, res = front_bundle
    skin = res.skin
    for layer, mask in zip(skin.layers[1:], skin.masks[1:]):
        grey = layer.astype(np.float64).mean(axis=2)
        # The mottle is the only fine detail: a few per cent of the skin's level.
        across = np.abs(np.diff(grey, axis=1))[mask[:, 1:] & mask[:, :-1]]
        assert np.percentile(across, 95) < 0.1 * np.median(grey[mask]), np.percentile(across, 95)
        rows = np.array([np.median(g[m]) if m.sum() > 20 else np.nan for g, m in zip(grey, mask)])
        ok = np.isfinite(rows)
        assert ok.sum() > 100
        assert np.abs(np.diff(rows[ok])).max() < 0.05 * np.median(grey[mask])


def test_front_only_matches_the_example_within_reach_of_the_two_photo_build(front_bundle, tmp_path):
    """The example person built from the front photo alone against the same person built
    from both photos: feature points within a few millimetres, the front agreeing better
    than the depth."""
    from recon.shape.fit import fit_head

    _, res = front_bundle
    both, _ = fit_head(read_fdp_json(EXAMPLE_FDP), ipd_mm=CAM["ipd_mm"], focal_px=CAM["focal_px"])
    a, b = res.head.fp_positions(), both.fp_positions()
    ids = [i for i in a if i in b and res.head.metadata["fit"]["point_sources"].get(i) == "front"]
    d = np.array([a[i] - b[i] for i in ids])
    d -= d.mean(axis=0)  # no common origin
    assert np.median(np.abs(d[:, :2])) * 1000 < 1.5
    assert np.median(np.abs(d[:, 2])) * 1000 < 5.0


@pytest.mark.parametrize("case", ["few points", "no pupils"])
def test_front_only_refuses_too_few_points(tmp_path, case):
    fdp = read_fdp_json(EXAMPLE_FDP)
    view = fdp.views["front"]
    if case == "few points":
        view.points = {i: p for i, p in list(view.points.items())[:5]}
    else:
        view.points = {i: p for i, p in view.points.items() if i not in ("3.5", "3.6")}
    fdp.views = {"front": view}
    view.image = str(EXAMPLE_DIR / "front.jpg")
    path = tmp_path / "f.fdp.json"
    write_fdp_json(path, fdp)
    with pytest.raises(InputError) as e:
        run_build(None, None, path, tmp_path / "out", texture_size=256)
    assert "front photo" in str(e.value) and "views.front" in str(e.value)
    assert not (tmp_path / "out").exists()


def test_a_side_photo_without_side_points_is_an_error(tmp_path):
    path = _front_only_fdp(tmp_path)
    with pytest.raises(InputError, match="no feature points for the side photo"):
        run_build(None, EXAMPLE_DIR / "side.jpg", path, tmp_path / "out", texture_size=256)


def test_front_photo_alone_is_detected_and_built(tmp_path):
    """recon build FRONT -o OUT: the points detected on the front photo (kept for
    correcting), the head built from them."""
    pytest.importorskip("mediapipe")
    paths = run_build(EXAMPLE_DIR / "front.jpg", None, None, tmp_path / "out", texture_size=256)
    found = read_fdp_json(paths["annotations"])
    assert list(found.views) == ["front"] and found.metadata["reviewed"] is False
    assert len(found.views["front"].points) >= 60
    meta = json.loads(paths["fdp"].read_text())["metadata"]
    assert "estimated" in meta["fit"]["depth"]


def test_side_photo_that_cuts_the_face_off_is_left_out_with_a_warning(tmp_path):
    """recon build FRONT SIDE, the side photo's edge through the face: no profile to read;
    the head is built from the front photo alone, saying so and why."""
    pytest.importorskip("mediapipe")
    from PIL import Image

    from recon.photos import read_photo

    side = read_photo(EXAMPLE_DIR / "side.jpg")
    Image.fromarray(np.ascontiguousarray(side[:, 226:])).save(tmp_path / "cut.png")  # the nose gone
    said = []
    paths = run_build(EXAMPLE_DIR / "front.jpg", tmp_path / "cut.png", None, tmp_path / "out", texture_size=256,
                      progress=said.append)
    warning = [m for m in said if "the side photo is not used" in m]
    assert warning and "runs off the photo's left edge" in warning[0] and "cut.png" in warning[0]
    assert list(read_fdp_json(paths["annotations"]).views) == ["front"]
    meta = json.loads(paths["fdp"].read_text())["metadata"]
    assert "estimated" in meta["fit"]["depth"]
    assert "runs off" in meta["provenance"]["side_photo_not_used"]
