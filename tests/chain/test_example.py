"""The README's main command: the embedded example end to end."""

import json

import cv2

from mpeg4.io import load_head
from chain.example import run_example

EXAMPLE = __import__("pathlib").Path(__file__).resolve().parents[2] / "data" / "example"


def test_example_writes_a_valid_head_fdp_and_preview(tmp_path, validate_gltf):
    import shutil

    messages = []
    speak = shutil.which("espeak-ng") is not None
    paths = run_example(tmp_path / "out", progress=messages.append, speak=speak, texture_size=1024)
    assert messages[-1].startswith("done in")
    report = validate_gltf(paths["head"])
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0
    head = load_head(paths["head"])
    assert len(head.feature_points) == 84 and len(head.morph_targets) == 55
    # The person's own shape and texture, not the generic head's.
    from mpeg4.generic_head import load_generic_head

    generic = load_generic_head()
    ipd = lambda h: float(((h.fp_position("3.5") - h.fp_position("3.6")) ** 2).sum() ** 0.5)  # noqa: E731
    # Its eyes as far apart as the photos' person's (69.16 mm; the generic head's: 67.21).
    person_ipd = 1e-3 * json.loads((EXAMPLE / "example.fdp.json").read_text())["metadata"]["synthetic"]["ipd_mm"]
    assert abs(ipd(head) - person_ipd) < 0.0005 < 0.0015 < abs(ipd(generic) - person_ipd)
    from scipy.spatial import cKDTree

    apart, _ = cKDTree(head.skin.vertices).query(generic.skin.vertices)  # the skin's seams split it
    assert float(apart.mean()) > 0.002  # the shape, not the generic head's
    assert head.skin.texture is not None and head.skin.texture.shape[:2] == (1024, 1024)
    assert head.skin.uv is not None and paths["texture"].exists() and paths["obj"].exists()
    assert len(head.fat) == 66 + 15 + 7  # every low-level FAP, the visemes and the expressions
    if speak:
        assert validate_gltf(paths["animation"])["issues"]["numErrors"] == 0
        assert paths["audio"].stat().st_size > 10000 and paths["speech_preview"].stat().st_size > 10000
    fdp = json.loads(paths["fdp"].read_text())
    assert len(fdp["points3d"]) == 84 and set(fdp["fapu"]) == {"IRISD0", "ES0", "ENS0", "MNS0", "MW0"}
    image = cv2.imread(str(paths["preview"]))
    assert image.shape[0] > 700 and image.shape[1] > 3 * 500  # three labelled views and a caption
    # Running again replaces the files in place.
    again = run_example(tmp_path / "out", speak=False, texture_size=256)
    assert again == {k: v for k, v in paths.items() if k in again}
