"""The generic head: built from the ICT FaceKit, its feature points, FAPU and morph targets."""

import importlib.util
import time
from pathlib import Path

import numpy as np
import pytest

from mpeg4 import FEATURE_POINTS, FP_IDS
from mpeg4.generic_head import GENERIC_HEAD_DIR, load_generic_head

ROOT = Path(__file__).resolve().parents[1]


def _builder():
    spec = importlib.util.spec_from_file_location("build_generic_head", ROOT / "scripts" / "build_generic_head.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def built(ict_npz):
    t0 = time.perf_counter()
    head = _builder().build_generic_head(ict_npz)
    return head, time.perf_counter() - t0


def test_builds_fast_with_all_points(built):
    head, seconds = built
    assert seconds < 60
    assert sorted(head.feature_points) == sorted(FP_IDS)
    assert list(head.parts) == ["skin", "eye_l", "eye_r", "teeth_upper", "teeth_lower", "gums_upper", "gums_lower",
                                "tongue"]
    assert head.skin.n_vertices == 14062


def test_fapu_in_adult_ranges(built):
    f = built[0].fapu
    assert 60e-3 <= f.ES0 <= 68e-3
    assert 45e-3 <= f.MW0 <= 55e-3
    assert 35e-3 <= f.ENS0 <= 50e-3
    assert 12e-3 <= f.MNS0 <= 22e-3
    # The lid margins at the pupil are 9.9 mm apart: ICT's neutral lids are a little closed
    # against the reference's ball-park of 10-13 mm (README).
    assert 9.5e-3 <= f.IRISD0 <= 13e-3


def test_left_right_mirror_and_midline(built):
    head = built[0]
    assert max(head.mirror_error().values()) < 1e-3
    for i in FP_IDS:
        p = head.fp_position(i)
        side = FEATURE_POINTS[i].side
        if side == "C":
            assert abs(p[0]) < 1e-6, i
        else:
            assert (p[0] > 0) == (side == "L"), i


def test_anatomical_orderings(built):
    h = built[0]
    y = {i: h.fp_position(i)[1] for i in FP_IDS}
    z = {i: h.fp_position(i)[2] for i in FP_IDS}
    x = {i: h.fp_position(i)[0] for i in FP_IDS}
    assert y["11.4"] == max(y.values())
    assert y["2.1"] == min(y[i] for i in FP_IDS if FEATURE_POINTS[i].group in (2, 8, 9) and i not in ("9.9",))
    assert y["8.1"] > y["2.2"] >= y["2.3"] > y["8.2"] > y["2.1"]
    assert y["3.1"] > y["3.5"] > y["3.3"] and y["4.3"] > y["3.13"] > y["3.1"]
    assert x["3.7"] > x["3.5"] > x["3.11"] > 0
    assert y["11.1"] > y["4.3"] > y["3.5"] > y["9.15"] > y["8.1"]
    assert z["9.3"] == max(z.values())
    assert z["11.6"] == min(z.values())
    assert y["10.1"] > y["10.5"] and z["10.3"] < z["10.7"]
    # The gonion 2.13 at the jaw's angle: below the lobe and above the chin, behind the chin's
    # corner and in front of the ear, between them sideways (not mid-cheek at the lobe's height).
    assert y["2.1"] < y["2.11"] < y["2.13"] < y["10.5"] - 0.02
    assert z["10.7"] < z["2.13"] < z["2.11"] and x["2.11"] < x["2.13"] < x["10.5"]
    # 7.1, the top of the spine, is inside the neck: behind the lobes, in front of the nape.
    assert z["11.6"] < z["7.1"] < z["10.5"] and abs(y["7.1"] - y["10.5"]) < 0.01


def test_eyes_turn_about_their_centres(built):
    for name, sign in (("eye_l", 1), ("eye_r", -1)):
        eye = built[0].parts[name]
        r = np.linalg.norm(eye.vertices - eye.centre, axis=1)
        assert sign * eye.centre[0] > 0.025
        # The sclera (ICT's first 770 eyeball vertices) is a ball about the centre.
        sclera = r[:770]
        assert sclera.max() - sclera.min() < 2.5e-3 and 0.013 < sclera.mean() < 0.017


def test_jaw_moves_the_lower_mouth_only(built):
    jaw = built[0].morph_targets["jawOpen"]
    for part in ("teeth_lower", "gums_lower", "tongue", "skin"):
        assert part in jaw and np.abs(jaw[part].vectors).max() > 0.01
    for part in ("teeth_upper", "eye_l"):
        assert part not in jaw or np.abs(jaw[part].vectors).max() < 0.003
    # The upper gums carry the back of the mouth floor, which follows the jaw a little.
    moving = np.linalg.norm(jaw["gums_upper"].vectors, axis=1) > 1e-3
    assert moving.sum() < 0.25 * built[0].parts["gums_upper"].n_vertices


def test_sparse_targets_equal_ict_deltas(built, ict_npz):
    head = built[0]
    data = np.load(ict_npz)
    names = [str(n) for n in data["expression_names"]]
    ids = np.arange(*head.metadata["ict_vertex_ids"]["skin"])
    for name in ("jawOpen", "mouthSmile_L", "eyeBlink_R"):
        dense = data["expression_deltas"][names.index(name)][ids].astype(np.float64) * 0.01
        mine = head.morph_targets[name]["skin"].dense(len(ids))
        assert np.abs(mine - dense).max() <= 1e-7


def test_committed_glb_equals_a_fresh_build(built):
    head = built[0]
    path = GENERIC_HEAD_DIR / "generic_head.glb"
    assert path.stat().st_size <= 15e6
    shipped = load_generic_head()
    assert list(shipped.parts) == list(head.parts)
    for name, p in head.parts.items():
        assert np.abs(shipped.parts[name].vertices - p.vertices).max() < 1e-6
        np.testing.assert_array_equal(shipped.parts[name].triangles, p.triangles)
        assert (shipped.parts[name].texture is None) == (p.texture is None), name
        if p.texture is not None:
            # The mouth's ramps: texture coordinates hold each vertex's light, found by
            # depth renders whose rounding may differ by a texel on another machine.
            assert np.abs(shipped.parts[name].texture.astype(int) - p.texture).max() <= 1, name
            du = np.abs(shipped.parts[name].uv - p.uv)
            assert np.median(du) < 1e-4 and du.max() < 0.05, name
    assert shipped.feature_points == head.feature_points
    assert sorted(shipped.morph_targets) == sorted(head.morph_targets)


def test_shipped_glb_is_valid(validate_gltf):
    report = validate_gltf(GENERIC_HEAD_DIR / "generic_head.glb")
    assert report["issues"]["numErrors"] == 0
