"""The notebooks run top to bottom, and the pictures they make are the gallery's.

Each notebook is executed in a fresh kernel (``scripts/make_gallery.py`` runs them the same
way), its time printed in the run's "notebooks" section; every GLB it writes passes the
Khronos validator; every picture it keeps is compared with ``docs/gallery/`` with a
tolerance, never byte for byte: the same libraries on another processor, or with another
number of threads, rasterise edges and round colours differently (:func:`picture_difference`).
"""

import hashlib
import importlib.util
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("make_gallery", ROOT / "scripts" / "make_gallery.py")
make_gallery = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(make_gallery)

NOTEBOOKS = make_gallery.notebooks()
#: Pictures are compared at a quarter of their size (4 × 4 blocks averaged), where a
#: rasteriser's sub-pixel edge shifts and rounding shrink below a grey level or two while
#: a changed face, curve or label still moves whole blocks. Bounds in grey levels (0-255):
#: the blocks' mean absolute difference, and the difference that 999 blocks in 1000 stay
#: under. A head drawn with another expression or turned by a few degrees moves far more
#: than 0.1 % of a figure's blocks by more than this.
BLOCK = 4
MEAN_TOLERANCE = 1.0
PEAK_TOLERANCE = 24.0


def _ict_present() -> bool:
    return (ROOT.parent / "shared" / "data" / "ict_facekit" / "ict_facekit.npz").exists()


def test_there_are_notebooks_and_their_outputs_are_stripped():
    import nbformat

    assert [p.stem[:2] for p in NOTEBOOKS] == ["01", "02", "03", "04"]
    for path in NOTEBOOKS:
        nb = nbformat.read(path, as_version=4)
        nbformat.validate(nb)
        code = [c for c in nb.cells if c.cell_type == "code"]
        assert code, path.name
        dirty = [k for k, c in enumerate(nb.cells) if c.cell_type == "code" and (c.outputs or c.execution_count)]
        assert not dirty, f"{path.name}: cells {dirty} keep outputs; clear them before committing"


def test_every_gallery_picture_is_listed_and_linked_from_the_readme():
    manifest = make_gallery.read_manifest()
    pictures = manifest["pictures"]
    on_disk = {p.name for p in make_gallery.GALLERY_DIR.glob("*.png")}
    assert on_disk == set(pictures), "docs/gallery and gallery.json disagree: run python3 scripts/make_gallery.py"
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    for name, entry in pictures.items():
        assert f"(docs/gallery/{name})" in readme, f"README.md does not link docs/gallery/{name}"
        data = (make_gallery.GALLERY_DIR / name).read_bytes()
        assert hashlib.sha256(data).hexdigest() == entry["sha256"], f"{name} is not the picture gallery.json lists"
        assert (make_gallery.NOTEBOOK_DIR / entry["notebook"]).exists(), entry["notebook"]


def picture_difference(x: np.ndarray, y: np.ndarray, block: int = BLOCK) -> tuple[float, float]:
    """Mean and 99.9th-percentile absolute difference of two (H, W, 3) uint8 pictures,
    grey levels, over ``block`` × ``block`` averages."""
    h, w = (x.shape[0] // block) * block, (x.shape[1] // block) * block

    def blocks(img):
        return img[:h, :w].astype(np.float64).reshape(h // block, block, w // block, block, -1).mean(axis=(1, 3))

    d = np.abs(blocks(x) - blocks(y))
    return float(d.mean()), float(np.percentile(d, 99.9))


def _compare(fresh: Path, kept: Path) -> tuple[str, float, float]:
    """What differs ('' when the pictures agree within what drawing on another machine
    changes), and the mean and peak block differences."""
    import cv2

    x = cv2.imread(str(fresh), cv2.IMREAD_COLOR)
    y = cv2.imread(str(kept), cv2.IMREAD_COLOR)
    if x.shape != y.shape:
        return f"is {x.shape[1]}x{x.shape[0]} instead of {y.shape[1]}x{y.shape[0]}", np.inf, np.inf
    mean, peak = picture_difference(x, y)
    if mean > MEAN_TOLERANCE or peak > PEAK_TOLERANCE:
        return f"differs by {mean:.2f} grey levels on average, {peak:.1f} at the 99.9th percentile", mean, peak
    return "", mean, peak


def test_the_picture_comparison_forgives_rasterising_and_catches_a_change():
    # What another processor does: edges shifted by a pixel here and there, colours rounded
    # the other way. What a real change does: a region of the picture drawn differently.
    rng = np.random.default_rng(7)
    picture = np.zeros((480, 640, 3), np.uint8)
    for k in range(40):
        x0, y0 = rng.integers(0, 600), rng.integers(0, 440)
        picture[y0:y0 + rng.integers(5, 60), x0:x0 + rng.integers(5, 60)] = rng.integers(0, 256, 3)
    shifted = picture.copy()
    rows = rng.random(480) < 0.1
    shifted[rows] = np.roll(picture[rows], 1, axis=1)  # a one-pixel edge shift on 10 % of the rows
    rounded = np.clip(shifted.astype(np.int16) + rng.integers(-1, 2, shifted.shape), 0, 255).astype(np.uint8)
    mean, peak = picture_difference(picture, rounded)
    assert mean <= MEAN_TOLERANCE and peak <= PEAK_TOLERANCE, (mean, peak)
    changed = picture.copy()
    changed[200:240, 300:350] = 255 - changed[200:240, 300:350]  # 0.65 % of the picture redrawn
    mean, peak = picture_difference(picture, changed)
    assert peak > PEAK_TOLERANCE, (mean, peak)


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs_and_remakes_its_gallery_pictures(path, tmp_path, request, notebook_report):
    gallery = tmp_path / "gallery"
    seconds = make_gallery.execute(path, tmp_path, gallery)
    line = f"{path.name}: executed in {seconds:.1f} s"

    glbs = sorted((tmp_path / "out").rglob("*.glb"))
    if glbs:
        try:
            validate = request.getfixturevalue("validate_gltf")
        except pytest.skip.Exception as e:
            line += f"; {len(glbs)} GLB not validated ({e})"
        else:
            for glb in glbs:
                issues = validate(glb)["issues"]
                assert issues["numErrors"] == 0, (glb.name, issues["messages"][:5])
            line += f"; {len(glbs)} GLB valid"

    manifest = make_gallery.read_manifest()
    expected = {n for n, p in manifest["pictures"].items() if p["notebook"] == path.name}
    made = {p.name for p in gallery.glob("*.png")}
    assert made <= expected, (f"{path.name} makes pictures the gallery lacks: {sorted(made - expected)}; "
                              "run python3 scripts/make_gallery.py")
    missing = sorted(expected - made)
    if missing:
        assert not _ict_present(), f"{path.name} no longer makes {missing}; run python3 scripts/make_gallery.py"
        line += f"; not made without the ICT FaceKit data: {', '.join(missing)}"
    compared = {n: _compare(gallery / n, make_gallery.GALLERY_DIR / n) for n in sorted(made)}
    wrong = {n: why for n, (why, _, _) in compared.items() if why}
    worst = max((c[1:] for c in compared.values()), default=(0.0, 0.0))
    line += f"; {len(made)} pictures compared with docs/gallery (worst: {worst[0]:.2f} mean, {worst[1]:.1f} peak grey levels)"
    notebook_report.append(line)
    assert not wrong, (f"{path.name}: pictures no longer match docs/gallery ({wrong}): if the change is meant, run "
                       "python3 scripts/make_gallery.py and look at them")


def test_make_gallery_names_an_unknown_notebook_in_one_line(capsys):
    assert make_gallery.main(["07"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("make_gallery: no notebook '07'") and "01_photos_to_head" in err and "\n" not in err
