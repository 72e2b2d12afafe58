"""recon build end to end on the embedded example; atlas; shape–texture separation; bad input."""

import json
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from mpeg4 import InputError
from mpeg4.io import read_fdp_json, write_fdp_json
from mpeg4.io.obj import read_obj
from recon.build import build_head, load_pair, run_build
from recon.example import EXAMPLE_DIR, EXAMPLE_FDP, example_camera

CAM = example_camera()


@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    out = tmp_path_factory.mktemp("build")
    paths = run_build(None, None, EXAMPLE_FDP, out, ipd_mm=CAM["ipd_mm"], focal_px=CAM["focal_px"],
                      texture_size=512)
    return out, paths


def test_build_writes_a_valid_textured_bundle(bundle, validate_gltf):
    out, paths = bundle
    for key in ("head", "obj", "mtl", "texture", "fdp", "preview"):
        assert paths[key].exists(), key
    report = validate_gltf(paths["head"])
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0, report["issues"]
    fdp = read_fdp_json(paths["fdp"])
    assert len(fdp.points3d) == 84 and len(fdp.texcoords) == 84
    uv = np.array(list(fdp.texcoords.values()))
    assert ((uv > 0) & (uv < 1)).all()
    prov = json.loads(paths["fdp"].read_text())["metadata"]["provenance"]
    assert prov["version"] and prov["options"]["texture_size"] == 512 and prov["options"]["focal_px"]
    assert len(prov["inputs"]["shape"]["front"]["sha256"]) == 64
    assert set(fdp.views) == {"front", "side"}
    # The OBJ comes back with its texture, feature points and the same vertices.
    head = read_obj(paths["obj"])
    assert head.skin.texture is not None and head.skin.texture.shape[:2] == (512, 512)
    assert (paths["texture"].parent / "head.mtl").read_text().count("map_Kd texture.png") == 1
    np.testing.assert_allclose(head.fp_position("9.3"), fdp.points3d["9.3"], atol=1e-6)
    # Nothing temporary is left behind.
    assert not [p for p in out.iterdir() if p.name.startswith(".")]
    preview = np.asarray(Image.open(paths["preview"]))
    assert preview.shape[1] > 2 * preview.shape[0]  # photos and three views side by side


def test_rebuilding_replaces_the_bundle_and_a_failed_build_keeps_it(bundle, tmp_path):
    out, paths = bundle
    before = paths["head"].read_bytes()
    bad = tmp_path / "bad.fdp.json"
    fdp = read_fdp_json(EXAMPLE_FDP)
    for view in fdp.views.values():
        view.image = str(EXAMPLE_DIR / view.image)
    fdp.views["front"].points.pop("3.5")
    fdp.views["front"].points.pop("3.6")
    write_fdp_json(bad, fdp)
    with pytest.raises(InputError):
        run_build(None, None, bad, out, texture_size=512)
    assert paths["head"].read_bytes() == before
    assert not [p for p in out.iterdir() if p.name.startswith(".")]


def test_atlas_is_non_overlapping_and_renders_the_same(bundle):
    from mpeg4.preview import head_meshes
    from mpeg4.render import render
    from recon.texture.atlas import repack

    pair = load_pair(EXAMPLE_FDP)
    result = build_head(pair, ipd_mm=CAM["ipd_mm"], focal_px=CAM["focal_px"], texture_size=512)
    packed = repack(result.head, size=512)
    skin = packed.parts["skin"]
    assert (skin.uv >= 0).all() and (skin.uv <= 1).all()
    np.testing.assert_allclose(packed.fp_position("9.3"), result.head.fp_position("9.3"))
    # Charts do not overlap: hardly a texel centre lies strictly inside two triangles.
    counts = _coverage(skin.uv, skin.triangles, 1024)
    assert (counts > 1).sum() < 1e-3 * (counts > 0).sum()
    assert (counts > 0).mean() > 0.3  # and the atlas is not mostly empty
    cam = result.cameras["front"].camera
    a = render(head_meshes(result.head), cam, ambient=1.0).astype(float)
    b = render(head_meshes(packed), cam, ambient=1.0).astype(float)
    assert np.mean(np.abs(a - b)) < 3.0


def _coverage(uv, tris, n):
    """(n * n,) how many triangles strictly contain each texel centre."""
    from recon.texture.bake import _barycentric, uv_to_pixels

    c = uv_to_pixels(uv, (n, n))[tris]
    lo, hi = np.floor(c.min(axis=1)).astype(int), np.ceil(c.max(axis=1)).astype(int)
    w = hi - lo + 1
    cnt = w[:, 0] * w[:, 1]
    tid = np.repeat(np.arange(len(tris)), cnt)
    off = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    x, y = lo[tid, 0] + off % w[tid, 0], lo[tid, 1] + off // w[tid, 0]
    b = _barycentric(np.c_[x, y].astype(float), c[tid], clamp=False)
    inside = (b.min(axis=1) > 1e-9) & (x >= 0) & (x < n) & (y >= 0) & (y < n)
    return np.bincount(y[inside] * n + x[inside], minlength=n * n)


def _mirrored_pair(tmp_path):
    """The example seen in a mirror: photos flipped, left and right labels swapped."""
    from mpeg4.catalogue import FEATURE_POINTS

    fdp = read_fdp_json(EXAMPLE_FDP)
    for name, view in fdp.views.items():
        img = Image.open(EXAMPLE_DIR / view.image).transpose(Image.FLIP_LEFT_RIGHT)
        img.save(tmp_path / f"m_{name}.png")
        view.image = f"m_{name}.png"
        view.points = {(FEATURE_POINTS[i].mirror or i) if name == "front" else i:
                       np.array([view.width - 1 - p[0], p[1]]) for i, p in view.points.items()}
    write_fdp_json(tmp_path / "mirror.fdp.json", fdp)
    return tmp_path / "mirror.fdp.json"


def test_shape_from_one_pair_texture_from_another(tmp_path):
    other = _mirrored_pair(tmp_path)
    a, b = load_pair(EXAMPLE_FDP), load_pair(other)
    opts = dict(ipd_mm=CAM["ipd_mm"], focal_px=CAM["focal_px"], texture_size=512)
    shape_only = build_head(a, **opts)
    texture_only = build_head(b, **opts)
    mixed = build_head(a, b, **opts)
    n = shape_only.head.skin.n_vertices - len(shape_only.head.metadata["duplicated_vertices"]["skin"])
    np.testing.assert_allclose(mixed.head.skin.vertices[:n], shape_only.head.skin.vertices[:n])
    np.testing.assert_array_equal(mixed.head.skin.uv, texture_only.head.skin.uv)
    np.testing.assert_array_equal(mixed.head.skin.texture, texture_only.head.skin.texture)
    # And through the command's function: the photos come from each file's views.
    paths = run_build(None, None, None, tmp_path / "out", shape_from=EXAMPLE_FDP, texture_from=other, **opts)
    prov = json.loads(paths["fdp"].read_text())["metadata"]["provenance"]
    assert prov["options"]["shape_texture_separation"] and "texture" in prov["inputs"]


def _cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "recon", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=300)


def test_bad_input_gives_one_clear_line(tmp_path):
    front, side = EXAMPLE_DIR / "front.jpg", EXAMPLE_DIR / "side.jpg"
    # Not an image.
    fake = tmp_path / "front.jpg"
    fake.write_text("not a photo")
    r = _cli("build", fake, side, "--fdp", EXAMPLE_FDP, "-o", tmp_path / "o")
    assert r.returncode == 2 and "not an image" in r.stderr and str(fake) in r.stderr
    # A missing file.
    r = _cli("build", tmp_path / "nope.jpg", side, "--fdp", EXAMPLE_FDP, "-o", tmp_path / "o")
    assert r.returncode == 2 and "nope.jpg" in r.stderr
    # Too small a photo (annotations scaled with it).
    small = tmp_path / "small"
    small.mkdir()
    fdp = read_fdp_json(EXAMPLE_FDP)
    for name, view in fdp.views.items():
        Image.open(EXAMPLE_DIR / view.image).resize((160, 200)).save(small / f"{name}.png")
        view.image, view.width, view.height = f"{name}.png", 160, 200
        view.points = {i: p * [160 / 1024, 200 / 1280] for i, p in view.points.items()}
    write_fdp_json(small / "s.fdp.json", fdp)
    r = _cli("build", "--fdp", small / "s.fdp.json", "-o", tmp_path / "o")
    assert r.returncode == 2 and "only 160x200 pixels" in r.stderr
    # Annotations made for other photos (another size).
    other = tmp_path / "big.png"
    Image.open(front).resize((1100, 1375)).save(other)
    r = _cli("build", other, side, "--fdp", EXAMPLE_FDP, "-o", tmp_path / "o")
    assert r.returncode == 2 and "1024x1280" in r.stderr and "1100x1375" in r.stderr
    # Both ways of giving annotations at once.
    r = _cli("build", "--fdp", EXAMPLE_FDP, "--shape-from", EXAMPLE_FDP, "-o", tmp_path / "o")
    assert r.returncode == 2 and "--shape-from" in r.stderr
    assert "Traceback" not in r.stderr


def test_a_profile_given_as_the_front_photo_is_refused(tmp_path):
    # The side photo and its points filed as the front view (and the front as the side).
    fdp = read_fdp_json(EXAMPLE_FDP)
    fdp.views["front"], fdp.views["side"] = fdp.views["side"], fdp.views["front"]
    for view in fdp.views.values():
        view.image = str(EXAMPLE_DIR / view.image)
    write_fdp_json(tmp_path / "swapped.fdp.json", fdp)
    with pytest.raises(InputError) as e:
        build_head(load_pair(tmp_path / "swapped.fdp.json"), ipd_mm=CAM["ipd_mm"], focal_px=CAM["focal_px"],
                   texture_size=256)
    assert "front" in str(e.value)


def test_photos_from_a_phone_are_turned_upright(tmp_path):
    from recon.photos import read_photo

    img = Image.open(EXAMPLE_DIR / "front.jpg")
    exif = Image.Exif()
    exif[0x0112] = 6  # stored sideways: viewers turn it 90° clockwise
    img.transpose(Image.ROTATE_90).save(tmp_path / "phone.jpg", exif=exif)
    np.testing.assert_allclose(read_photo(tmp_path / "phone.jpg").astype(float).mean(),
                               np.asarray(img).astype(float).mean(), atol=1.0)
    assert read_photo(tmp_path / "phone.jpg").shape == np.asarray(img).shape


# --- photos checked against their roles, even with --fdp ------------------------------------

@pytest.mark.parametrize("case", ["same photo twice", "swapped"])
def test_photos_that_do_not_fit_their_roles_are_refused_with_annotations_given(tmp_path, case):
    pytest.importorskip("mediapipe")
    from mpeg4 import InputError
    from recon.build import run_build
    from recon.example import EXAMPLE_DIR

    front, side = EXAMPLE_DIR / "front.jpg", EXAMPLE_DIR / "side.jpg"
    photos = (front, front) if case == "same photo twice" else (side, front)
    why = "the same picture" if case == "same photo twice" else "swap them"
    with pytest.raises(InputError, match=why):
        run_build(*photos, EXAMPLE_DIR / "example.fdp.json", tmp_path / "out")
    assert not (tmp_path / "out" / "head.glb").exists()


# --- recon build FRONT SIDE -o OUT: the points detected, kept, correctable ---------------------

def test_build_without_annotations_detects_writes_and_keeps_the_points(tmp_path):
    pytest.importorskip("mediapipe")
    from mpeg4 import InputError
    from mpeg4.io import read_fdp_json, write_fdp_json
    from recon.build import run_build
    from recon.example import EXAMPLE_DIR

    front, side = EXAMPLE_DIR / "front.jpg", EXAMPLE_DIR / "side.jpg"
    said, built = [], []
    paths = run_build(front, side, None, tmp_path / "a", texture_size=256, progress=said.append, result=built)
    found = read_fdp_json(paths["annotations"])
    # The time split: each step's seconds, within the whole run's.
    t = built[0].timings
    steps = [t[k] for k in ("detection", "shape", "texture", "export")]
    assert all(s > 0 for s in steps) and sum(steps) <= t["total"] + 1e-6
    assert any(m.startswith("done in") and "detection" in m and "export" in m for m in said)
    assert paths["annotations"] == tmp_path / "a" / "annotations.fdp.json" and found.metadata["reviewed"] is False
    assert (tmp_path / "a" / "head.glb").exists()
    assert any("recon annotate" in m and "--fdp" in m for m in said)
    head_meta = read_fdp_json(tmp_path / "a" / "head.fdp.json").metadata
    assert head_meta["provenance"]["inputs"]["shape"]["fdp"]["path"].endswith("annotations.fdp.json")
    # A failed build keeps the detected points and says how to correct them.
    with pytest.raises(InputError, match="detected automatically and are kept.*recon annotate"):
        run_build(front, side, None, tmp_path / "b", texture_size=256, height_tol_mm=0.001)
    assert read_fdp_json(tmp_path / "b" / "annotations.fdp.json").metadata["reviewed"] is False
    assert not (tmp_path / "b" / "head.glb").exists()
    # Points a person reviewed are never replaced by a new detection.
    found.metadata["reviewed"] = True
    write_fdp_json(tmp_path / "b" / "annotations.fdp.json", found)
    with pytest.raises(InputError, match="a person placed or checked"):
        run_build(front, side, None, tmp_path / "b", texture_size=256)
    with pytest.raises(InputError, match="neither left nor right"):
        run_build(front, side, None, tmp_path / "c", side_facing="up")


@pytest.mark.slow
def test_a_pair_of_huge_photos_builds_under_2_gb_and_gives_the_same_head(tmp_path):
    """The example photos blown up to 9600 x 12000 (115 megapixels; a 12000 x 9000 pair took
    9.2 GB before photos were read smaller): the child measures its own peak memory."""
    import textwrap
    from pathlib import Path

    from recon.photos import MAX_PHOTO_PIXELS

    w, h = 9600, 12000
    fdp = read_fdp_json(EXAMPLE_FDP)
    for name, view in fdp.views.items():
        im = Image.open(EXAMPLE_DIR / view.image)
        sx, sy = w / im.width, h / im.height
        im.resize((w, h), Image.BILINEAR).save(tmp_path / f"{name}.jpg", quality=85)
        view.points = {i: (p + 0.5) * [sx, sy] - 0.5 for i, p in view.points.items()}
        view.image, view.width, view.height = f"{name}.jpg", w, h
    write_fdp_json(tmp_path / "big.fdp.json", fdp)
    focal = CAM["focal_px"] * w / 1024
    root = Path(__file__).resolve().parents[2]
    script = textwrap.dedent(f'''
        import sys
        sys.path.insert(0, {str(root)!r})
        from recon.build import run_build
        run_build(None, None, {str(tmp_path / "big.fdp.json")!r}, {str(tmp_path / "out")!r}, ipd_mm={CAM["ipd_mm"]},
                  focal_px={focal}, texture_size=1024)
        # This process's own peak (VmHWM): ru_maxrss keeps, across exec, the peak of the
        # forked copy of the test runner, which may be larger than the build.
        print(next(int(line.split()[1]) for line in open('/proc/self/status') if line.startswith('VmHWM')) / 1024)
    ''')
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    peak_mb = float(run.stdout.split()[-1])
    assert peak_mb < 2048, f"peak {peak_mb:.0f} MB"
    # The same head as from the photos at their own size, the annotations as given.
    small = run_build(None, None, EXAMPLE_FDP, tmp_path / "small", ipd_mm=CAM["ipd_mm"], focal_px=CAM["focal_px"],
                      texture_size=256)
    big, ref = read_fdp_json(tmp_path / "out" / "head.fdp.json"), read_fdp_json(small["fdp"])
    moved = [np.linalg.norm(big.points3d[i] - ref.points3d[i]) for i in ref.points3d]
    assert max(moved) < 1e-4  # metres
    assert big.views["front"].width == w and np.allclose(big.views["front"].points["9.3"], fdp.views["front"].points["9.3"])
    assert w * h > MAX_PHOTO_PIXELS
