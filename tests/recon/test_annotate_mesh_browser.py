"""recon annotate MESH (the 3D mode) in a real browser: Playwright driving Debian's Chromium.

Starts ``python -m recon annotate MESH`` on a re-meshed ICT identity (an OBJ of anonymous
groups, in another unit and axes) whose points ``fmc mark`` saved (with the perfect 2D detector), drags a point over the
surface, undoes and redoes, saves, reloads, and checks the saved point lies on the mesh.
"""

import os
from pathlib import Path

import numpy as np
import pytest
import trimesh

from mpeg4.io import load_head, read_fdp_json

ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = ROOT / "test-artifacts"
CHROMIUM = "/usr/bin/chromium"
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--no-first-run"]

sync_api = pytest.importorskip("playwright.sync_api", reason="playwright is not installed (pip install '.[test]')")
pytest.importorskip("fast_simplification", reason="fast-simplification is not installed (pip install '.[test]')")
if not os.path.exists(CHROMIUM):
    pytest.skip(f"Chromium not found at {CHROMIUM} (apt-get install chromium)", allow_module_level=True)
if not (ROOT / "recon" / "annotate" / "static" / "vendor" / "three.bundle.js").exists():
    pytest.skip("three.js is not bundled (npm ci && npm run build)", allow_module_level=True)


@pytest.fixture(scope="module")
def marked(remeshed, tmp_path_factory):
    from recon.mark import mark_file
    from recon.evaluate.synthetic import perfect_detector

    mf = remeshed(7, "obj")
    mesh = tmp_path_factory.mktemp("mesh") / mf.path.name
    mesh.write_bytes(mf.path.read_bytes())
    fdp, _ = mark_file(mesh, detect=perfect_detector(mf.points), passes=1)
    return mesh, fdp


def _point(page, fp_id):
    return np.array(page.evaluate(f"() => annotate.store.point('mesh', '{fp_id}')"))


def _screen(page, fp_id):
    return np.array(page.evaluate(f"() => annotate.view.screenOf('{fp_id}')"))


@pytest.mark.slow
def test_drag_a_point_over_the_mesh_save_reload(marked, annotate_cli):
    mesh, fdp = marked
    before = read_fdp_json(fdp).points3d
    proc, url = annotate_cli.start(mesh, "--fdp", fdp)
    ARTIFACTS.mkdir(exist_ok=True)
    try:
        with sync_api.sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=FLAGS)
            page = browser.new_page(viewport={"width": 1300, "height": 860})
            errors = []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(url)
            page.wait_for_selector("body[data-ready=true]", timeout=30000)
            assert page.get_attribute("body", "data-mode") == "mesh"
            assert "loaded from" in page.inner_text("#init-message")
            assert page.locator("#view-front").is_hidden() and page.locator("#view-mesh").is_visible()
            assert int(page.get_attribute("#view-mesh .view-body", "data-meshes")) >= 5
            assert np.allclose(_point(page, "5.3"), before["5.3"], atol=1e-8)

            # Drag the left cheekbone point over the cheek.
            start = _point(page, "5.3")
            at = _screen(page, "5.3")
            page.mouse.move(*at)
            page.mouse.down()
            page.mouse.move(at[0] + 14, at[1] + 18, steps=6)
            page.mouse.up()
            moved = _point(page, "5.3")
            assert 0.002 < np.linalg.norm(moved - start) < 0.05
            assert np.allclose(_screen(page, "5.3"), at + [14, 18], atol=1.5)  # the marker followed the pointer
            assert page.evaluate("() => annotate.store.confidence('mesh', '5.3')") is None  # placed by hand
            page.screenshot(path=ARTIFACTS / "annotate_mesh_drag.png")
            page.keyboard.press("Control+z")
            assert np.allclose(_point(page, "5.3"), start)
            page.keyboard.press("Control+Shift+Z")
            assert np.allclose(_point(page, "5.3"), moved)

            page.keyboard.press("Control+s")
            page.wait_for_function("() => document.getElementById('file-status').textContent.includes(': saved')",
                                   timeout=10000)
            saved = read_fdp_json(fdp)
            # On the surface: the binding's point is the saved point, and the mesh passes through it.
            head = load_head(mesh)
            assert np.allclose(head.fp_position("5.3"), saved.points3d["5.3"], atol=1e-7)
            assert np.linalg.norm(saved.points3d["5.3"] - moved) < 1e-4
            allv = np.concatenate([q.vertices for q in head.parts.values()])
            off = 0
            tris = []
            for q in head.parts.values():
                tris.append(q.triangles + off)
                off += q.n_vertices
            surface = trimesh.Trimesh(allv, np.concatenate(tris), process=False)
            _, dist, _ = trimesh.proximity.closest_point(surface, saved.points3d["5.3"][None])
            assert dist[0] < 1e-6
            assert "5.3" not in saved.metadata["mark3d"]["confidence"]
            for i in ("2.1", "3.5", "9.3"):
                assert np.allclose(saved.points3d[i], before[i], atol=1e-7)  # untouched
            assert fdp.with_name(fdp.name + ".bak").exists()  # fmc mark's file kept

            page.reload()
            page.wait_for_selector("body[data-ready=true]", timeout=30000)
            assert np.allclose(_point(page, "5.3"), saved.points3d["5.3"], atol=1e-8)
            assert page.is_disabled("#btn-undo")
            assert errors == []
            browser.close()
    finally:
        annotate_cli.stop(proc)
    assert proc.returncode == 0, proc.stderr.read()
