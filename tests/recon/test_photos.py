"""Reading photos: the focal length a camera records in EXIF."""

import numpy as np
import pytest
from PIL import Image

from recon.photos import FILM_DIAGONAL_MM, exif_focal_px, photos_focal_px


def _photo(path, size=(800, 1000), focal_35mm=None, orientation=None, lens=None):
    exif = Image.Exif()
    if focal_35mm is not None:
        exif.get_ifd(0x8769)[0xA405] = focal_35mm
    if lens is not None:  # focal length (mm), sensor resolution (px/cm), recorded width (px)
        ifd = exif.get_ifd(0x8769)
        ifd[0x920A], ifd[0xA20E], ifd[0xA210], ifd[0xA002] = lens[0], lens[1], 3, lens[2]
    if orientation is not None:
        exif[0x0112] = orientation
    Image.new("RGB", size, (120, 110, 100)).save(path, exif=exif)
    return path


def test_focal_length_in_pixels_from_the_35mm_equivalent(tmp_path):
    f, f35 = exif_focal_px(_photo(tmp_path / "a.jpg", focal_35mm=26))
    assert f35 == 26 and f == pytest.approx(26 / FILM_DIAGONAL_MM * np.hypot(800, 1000), rel=1e-9)
    # The same lens on a photo stored sideways (the diagonal does not turn) and at half size.
    assert exif_focal_px(_photo(tmp_path / "b.jpg", (1000, 800), 26, orientation=6))[0] == pytest.approx(f)
    assert exif_focal_px(_photo(tmp_path / "c.jpg", (400, 500), 26))[0] == pytest.approx(f / 2)
    assert exif_focal_px(_photo(tmp_path / "d.jpg")) is None
    Image.new("RGB", (64, 64)).save(tmp_path / "e.png")
    assert exif_focal_px(tmp_path / "e.png") is None


def test_focal_length_in_pixels_from_the_lens_and_the_sensor(tmp_path):
    # The example's camera: 100 mm on a sensor of 53.33 px/mm (1280 px over 24 mm).
    f, f35 = exif_focal_px(_photo(tmp_path / "a.jpg", (1024, 1280), 141, lens=(100.0, 533.333333, 1024)))
    assert f == pytest.approx(5333.33, abs=0.01)  # the lens and sensor win over the rounded 35 mm figure
    assert f35 == pytest.approx(5333.33 / np.hypot(1024, 1280) * FILM_DIAGONAL_MM, rel=1e-6)
    # Downsized to half: the recorded width says so.
    assert exif_focal_px(_photo(tmp_path / "b.jpg", (512, 640), lens=(100.0, 533.333333, 1024)))[0] == \
        pytest.approx(2666.67, abs=0.01)


def test_one_focal_length_for_a_pair_or_orthographic_cameras(tmp_path):
    a = _photo(tmp_path / "a.jpg", focal_35mm=52)
    b = _photo(tmp_path / "b.jpg", focal_35mm=52)
    f, note = photos_focal_px(a, b)
    assert f == pytest.approx(52 / FILM_DIAGONAL_MM * np.hypot(800, 1000)) and "EXIF (52 mm" in note
    none = _photo(tmp_path / "n.jpg")
    f, note = photos_focal_px(none, none)
    assert f is None and "orthographic" in note
    f, note = photos_focal_px(a, none)
    assert f is None and "not the side photo" in note
    f, note = photos_focal_px(a, _photo(tmp_path / "w.jpg", focal_35mm=26))
    assert f is None and "different focal lengths (52 and 26 mm" in note


def test_the_annotation_preview_uses_the_recorded_focal_length(tmp_path):
    from recon.annotate import AnnotationSession

    a = _photo(tmp_path / "a.jpg", focal_35mm=52)
    b = _photo(tmp_path / "b.jpg", focal_35mm=52)
    s = AnnotationSession(a, b, tmp_path / "x.fdp.json", detect=False)
    assert s.fit_options["focal_px"] == pytest.approx(photos_focal_px(a, b)[0]) and "EXIF" in s.camera_note
    s.close()
    s = AnnotationSession(a, b, tmp_path / "x.fdp.json", detect=False, focal_px=1234.0)
    assert s.fit_options["focal_px"] == 1234.0
    s.close()


def test_recon_fit_on_the_example_takes_the_lens_from_exif(tmp_path):
    """The example's photos record their camera (100 mm on a 53.33 px/mm sensor): recon fit
    without --focal fits as with --focal 5333.33; the same photos with only the rounded
    35 mm equivalent (141 mm) a phone would record fit within a fraction of a millimetre."""
    from mpeg4.io import load_head
    from recon.example import EXAMPLE_DIR, EXAMPLE_FDP, example_camera
    from recon.shape.fit import run_fit

    cam = example_camera()
    for name in ("front", "side"):
        exif = Image.Exif()
        exif.get_ifd(0x8769)[0xA405] = 141
        Image.open(EXAMPLE_DIR / f"{name}.jpg").save(tmp_path / f"{name}.jpg", exif=exif, quality=95)
    said = []
    heads = {}
    for label, folder, focal in (("exif", EXAMPLE_DIR, None), ("35mm", tmp_path, None),
                                 ("given", EXAMPLE_DIR, cam["focal_px"])):
        paths = run_fit(folder / "front.jpg", folder / "side.jpg", EXAMPLE_FDP, tmp_path / label,
                        ipd_mm=cam["ipd_mm"], focal_px=focal, progress=said.append)
        heads[label] = load_head(paths["head"]).fp_positions()
    assert "focal length 5333 px from the photos' EXIF (141 mm, 35 mm equivalent)" in said
    assert "focal length 5342 px from the photos' EXIF (141 mm, 35 mm equivalent)" in said
    given = heads["given"]
    assert max(np.linalg.norm(heads["exif"][i] - given[i]) for i in given) < 1e-9
    assert max(np.linalg.norm(heads["35mm"][i] - given[i]) for i in given) < 0.5e-3  # metres


def test_a_photo_over_the_limit_is_read_smaller_and_its_points_follow(tmp_path):
    from mpeg4.io.fdp_json import ViewAnnotation
    from recon.photos import MAX_PHOTO_PIXELS, photo_scale, photo_size, read_photo, view_at_size

    # One factor for a pair, from the larger photo; none below the limit.
    assert photo_scale([(4000, 3000), (3000, 2000)]) == pytest.approx(np.sqrt(MAX_PHOTO_PIXELS / 12e6))
    assert photo_scale([(2000, 1500), (1000, 800)]) == 1.0
    # A photo with a bright square at known pixels, stored sideways (EXIF 6): read at a
    # quarter, the square is where the points say it is.
    img = np.zeros((800, 1200, 3), np.uint8)
    img[300:340, 700:760] = 255  # displayed: rows 300..339, columns 700..759
    Image.fromarray(np.rot90(img, 1).copy()).save(tmp_path / "p.jpg", quality=95,
                                                  exif=_exif({0x0112: 6}))
    assert photo_size(tmp_path / "p.jpg") == (1200, 800)
    small = read_photo(tmp_path / "p.jpg", scale=0.25)
    assert small.shape == (200, 300, 3)
    view = ViewAnnotation(None, 1200, 800, {"9.3": np.array([729.5, 319.5])})
    p = view_at_size(view, 300, 200).points["9.3"]
    ys, xs = np.nonzero(small.mean(axis=2) > 128)
    assert abs(xs.mean() - p[0]) < 0.5 and abs(ys.mean() - p[1]) < 0.5
    back = view_at_size(view_at_size(view, 300, 200), 1200, 800).points["9.3"]
    np.testing.assert_allclose(back, view.points["9.3"], atol=1e-9)


def _exif(tags):
    exif = Image.Exif()
    for k, v in tags.items():
        exif[k] = v
    return exif


# --- every format a camera or an editor writes ---------------------------------------------

def _formats(folder):
    """(file, expected RGB mean) for one picture written in many formats."""
    import cv2
    from PIL import Image

    ramp = np.linspace(0.0, 1.0, 120 * 160).reshape(120, 160)
    grey8 = np.round(ramp * 255).astype(np.uint8)
    grey16 = np.round(ramp * 65535).astype(np.uint16)
    colour = np.dstack([grey8, grey8 // 2, 255 - grey8])
    out = []
    cv2.imwrite(str(folder / "grey8.png"), grey8)
    out.append(("grey8.png", grey8.mean()))
    cv2.imwrite(str(folder / "grey16.png"), grey16)  # read as a blank white picture before
    out.append(("grey16.png", grey8.mean()))
    cv2.imwrite(str(folder / "colour16.png"), (colour.astype(np.uint16) * 257)[..., ::-1])
    out.append(("colour16.png", colour.mean()))
    Image.fromarray(np.dstack([colour, np.full((120, 160), 128, np.uint8)]), "RGBA").save(folder / "alpha.png")
    out.append(("alpha.png", colour.mean()))
    Image.fromarray(colour).convert("CMYK").save(folder / "cmyk.jpg", quality=95)
    out.append(("cmyk.jpg", colour.mean()))
    Image.fromarray(colour).save(folder / "colour.tif")
    out.append(("colour.tif", colour.mean()))
    Image.fromarray(grey16).save(folder / "grey16.tif")
    out.append(("grey16.tif", grey8.mean()))
    return out


def test_every_photo_format_is_read_as_it_looks(tmp_path):
    from recon.photos import read_photo

    for name, mean in _formats(tmp_path):
        img = read_photo(tmp_path / name)
        assert img.shape == (120, 160, 3) and img.dtype == np.uint8, name
        # 8-bit rounding, and JPEG's and CMYK's conversion for the JPEG.
        assert abs(img.astype(float).mean() - mean) < (6.0 if name.endswith(".jpg") else 1.0), (name, img.mean(), mean)
        half = read_photo(tmp_path / name, scale=0.5)
        assert half.shape == (60, 80, 3) and abs(half.astype(float).mean() - mean) < 6.0, name
