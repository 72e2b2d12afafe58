"""The notebooks run top to bottom, and the pictures they make are the gallery's.

Each notebook is executed in a fresh kernel (``scripts/make_gallery.py`` runs them the same
way), its time printed in the run's "notebooks" section; every GLB it writes passes the
Khronos validator; every picture it keeps is compared with ``docs/gallery/``: byte for byte
when this machine draws as the one that made the gallery (``gallery.json`` records the
OpenGL renderer and the libraries that rasterise and encode), pixel by pixel otherwise, the
section saying why.
"""

import hashlib
import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("make_gallery", ROOT / "scripts" / "make_gallery.py")
make_gallery = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(make_gallery)

NOTEBOOKS = make_gallery.notebooks()
#: When the machine differs from the gallery's: largest mean absolute difference per picture, grey levels.
PIXEL_TOLERANCE = 2.0


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


def _compare(fresh: Path, kept: Path, byte_for_byte: bool) -> str:
    """'' when the pictures agree as they should; otherwise what differs."""
    a, b = fresh.read_bytes(), kept.read_bytes()
    if a == b:
        return ""
    if byte_for_byte:
        return "differs byte for byte"
    import cv2

    x = cv2.imdecode(np.frombuffer(a, np.uint8), cv2.IMREAD_COLOR)
    y = cv2.imdecode(np.frombuffer(b, np.uint8), cv2.IMREAD_COLOR)
    if x.shape != y.shape:
        return f"is {x.shape[1]}x{x.shape[0]} instead of {y.shape[1]}x{y.shape[0]}"
    diff = float(np.abs(x.astype(np.int16) - y).mean())
    return f"differs by {diff:.2f} grey levels on average" if diff > PIXEL_TOLERANCE else ""


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
    here = make_gallery.environment()
    same = here == manifest["environment"]
    wrong = {n: why for n in sorted(made)
             if (why := _compare(gallery / n, make_gallery.GALLERY_DIR / n, byte_for_byte=same))}
    if same:
        line += f"; {len(made)} pictures identical to docs/gallery"
    else:
        changed = {k: f"{manifest['environment'].get(k)} -> {v}" for k, v in here.items()
                   if manifest["environment"].get(k) != v}
        line += (f"; {len(made)} pictures within {PIXEL_TOLERANCE} grey levels of docs/gallery, not compared byte for "
                 f"byte: the gallery was drawn elsewhere ({json.dumps(changed)})")
    notebook_report.append(line)
    assert not wrong, (f"{path.name}: pictures no longer match docs/gallery ({wrong}): if the change is meant, run "
                       "python3 scripts/make_gallery.py and look at them")


def test_make_gallery_names_an_unknown_notebook_in_one_line(capsys):
    assert make_gallery.main(["07"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("make_gallery: no notebook '07'") and "01_photos_to_head" in err and "\n" not in err
