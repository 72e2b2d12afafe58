"""Reading photos: the focal length a camera records in EXIF."""

import numpy as np
import pytest
from PIL import Image

from recon.photos import FILM_DIAGONAL_MM, exif_focal_px, photos_focal_px


def _photo(path, size=(800, 1000), focal_35mm=None, orientation=None):
    exif = Image.Exif()
    if focal_35mm is not None:
        exif.get_ifd(0x8769)[0xA405] = focal_35mm
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
    """The example's photos (100 mm lens on a 24 mm high frame: 5333.33 px) given the
    35 mm equivalent a camera would record (141 mm on their 1639 px diagonal) fit like
    the same photos with --focal."""
    from mpeg4.io import load_head
    from recon.example import EXAMPLE_DIR, EXAMPLE_FDP, example_camera
    from recon.fit import run_fit

    cam = example_camera()
    for name in ("front", "side"):
        exif = Image.Exif()
        exif.get_ifd(0x8769)[0xA405] = 141
        Image.open(EXAMPLE_DIR / f"{name}.jpg").save(tmp_path / f"{name}.jpg", exif=exif, quality=95)
    said = []
    heads = {}
    for label, focal in (("exif", None), ("given", cam["focal_px"])):
        paths = run_fit(tmp_path / "front.jpg", tmp_path / "side.jpg", EXAMPLE_FDP, tmp_path / label,
                        ipd_mm=cam["ipd_mm"], focal_px=focal, progress=said.append)
        heads[label] = load_head(paths["head"])
    assert any("from the photos' EXIF (141 mm" in m for m in said)
    fit = heads["exif"].metadata["fit"]
    assert fit["camera"].startswith("perspective, focal length 53")
    a, b = heads["exif"].fp_positions(), heads["given"].fp_positions()
    assert max(np.linalg.norm(a[i] - b[i]) for i in a) < 0.5e-3  # metres
