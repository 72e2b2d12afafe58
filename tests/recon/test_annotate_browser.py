"""recon annotate in a real browser: Playwright driving Debian's Chromium against the command.

Starts ``python -m recon annotate`` on the example photos, drags points, checks the
same-height guide and mirrored placement against the geometry computed here, undoes and
redoes, saves, reloads, and reads the saved file. Screenshots go to ``test-artifacts/``.
"""

import io
import json
import os
import re
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from mpeg4 import FEATURE_POINTS
from mpeg4.io import read_fdp_json

ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = ROOT / "test-artifacts"
CHROMIUM = "/usr/bin/chromium"
# Debian's Chromium, headless, nothing fetched from the network (see FACTS.md).
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--no-first-run"]

sync_api = pytest.importorskip("playwright.sync_api", reason="playwright is not installed (pip install '.[test]')")
if not os.path.exists(CHROMIUM):
    pytest.skip(f"Chromium not found at {CHROMIUM} (apt-get install chromium)", allow_module_level=True)


@pytest.fixture(scope="module")
def photos():
    """The embedded example: a front and a side photo of a synthetic person."""
    paths = [ROOT / "data" / "example" / f"{name}.jpg" for name in ("front", "side")]
    for p in paths:
        if not p.exists():
            pytest.skip(f"the example photo {p} is missing (python3 scripts/make_example_photos.py)")
    return paths


@pytest.fixture(scope="module")
def browser():
    with sync_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=FLAGS)
        yield b
        b.close()


def _open(browser, url, timeout=20000):
    """A page on the annotation app, ready; and the list its script errors go to."""
    page = browser.new_page(viewport={"width": 1400, "height": 860})
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(url)
    page.wait_for_selector("body[data-ready=true]", timeout=timeout)
    return page, errors


def _point(page, view, fp_id):
    el = page.locator(f'svg.photo[data-view="{view}"] .pt[data-id="{fp_id}"]')
    return np.array([float(el.get_attribute("data-x")), float(el.get_attribute("data-y"))])


def _centre(page, view, fp_id):
    box = page.locator(f'svg.photo[data-view="{view}"] .pt[data-id="{fp_id}"] .dot').bounding_box()
    return np.array([box["x"] + box["width"] / 2, box["y"] + box["height"] / 2])


def _view(page, view):
    return page.evaluate(f"() => {{ const v = annotate.views.{view}; return [v.scale, v.tx, v.ty]; }}")


def _points(page):
    return page.evaluate("() => annotate.store.toJSON()")


def _height_map(front, side, exclude):
    """Side-photo height → front-photo height across the eye line, as recon.shape.calibrate measures."""
    across = front["3.5"] - front["3.6"]
    across /= np.linalg.norm(across)
    up = np.array([across[1], -across[0]])
    mid = (front["3.5"] + front["3.6"]) / 2
    pairs = []
    for i, p in side.items():
        twin = i if i in front else FEATURE_POINTS[i].mirror
        if i not in exclude and twin in front and twin not in exclude:
            pairs.append((-p[1], (front[twin] - mid) @ up))
    hs, hf = np.array(pairs).T
    a, b = np.polyfit(hs, hf, 1)
    return lambda p: (-((p - mid) @ up - b) / a)  # front point → side-photo row


def _midline_reflection(front, exclude):
    on = [p for i, p in front.items() if i not in exclude and FEATURE_POINTS[i].side == "C"]
    on += [(p + front[FEATURE_POINTS[i].mirror]) / 2 for i, p in front.items()
           if i not in exclude and FEATURE_POINTS[i].side == "L" and FEATURE_POINTS[i].mirror in front
           and FEATURE_POINTS[i].mirror not in exclude]
    on = np.array(on)
    c = on.mean(axis=0)
    d = np.linalg.svd(on - c)[2][0]
    return lambda p: 2 * (c + ((p - c) @ d) * d) - p


def test_drag_guides_mirror_undo_redo_save_reload(photos, browser, tmp_path, annotate_cli):
    fdp = tmp_path / "head.fdp.json"
    # The generic head's points, whose heights agree between the photos, so that what the
    # 3D preview refuses below is the drag alone (automatic points are tested elsewhere).
    proc, url = annotate_cli.start(*photos, "--fdp", fdp, "--no-detect")
    ARTIFACTS.mkdir(exist_ok=True)
    try:
        page, errors = _open(browser, url)
        message = page.inner_text("#init-message")
        assert "generic head" in message, message
        conf_35 = page.evaluate("() => annotate.store.confidence('front', '3.5')")
        state = {v: {i: np.array(p) for i, p in pts["points"].items()} for v, pts in _points(page).items()}
        assert len(state["front"]) == 72 and len(state["side"]) == 37

        # Drag the nose tip: the same-height line shows in both photos while dragging.
        start = _point(page, "front", "9.3")
        scale, _, _ = _view(page, "front")
        at = _centre(page, "front", "9.3")
        page.mouse.move(*at)
        page.mouse.down()
        page.mouse.move(at[0] + 40, at[1] + 25, steps=6)
        front_guides = page.locator('svg.photo[data-view="front"] line.guide-height')
        side_guides = page.locator('svg.photo[data-view="side"] line.guide-height')
        assert front_guides.count() == 1 and side_guides.count() == 1
        moved = start + np.array([40, 25]) / scale
        assert np.allclose(_point(page, "front", "9.3"), moved, atol=0.05)
        # The side line sits at the row the points seen in both photos map this height to.
        s_scale, _, s_ty = _view(page, "side")
        y1, y2 = (float(side_guides.get_attribute(k)) for k in ("y1", "y2"))
        assert y1 == pytest.approx(y2)
        assert 0 < y1 < page.locator('svg.photo[data-view="side"]').bounding_box()["height"]  # inside the view
        row = _height_map(state["front"], state["side"], {"9.3"})(moved)
        assert (y1 - s_ty) / s_scale == pytest.approx(row, abs=0.05)
        page.screenshot(path=ARTIFACTS / "annotate_drag.png")
        page.mouse.up()
        assert page.locator("line.guide-height").count() == 0

        # Undo and redo the drag.
        page.keyboard.press("Control+z")
        assert np.allclose(_point(page, "front", "9.3"), start, atol=1e-9)
        page.keyboard.press("Control+Shift+Z")
        assert np.allclose(_point(page, "front", "9.3"), moved, atol=0.05)

        # Mirror mode: dragging the left pupil puts the right one at its mirror image.
        page.keyboard.press("m")
        assert page.get_attribute("#btn-mirror", "aria-pressed") == "true"
        assert page.locator('svg.photo[data-view="front"] line.guide-midline').count() == 1
        now = {i: np.array(p) for i, p in _points(page)["front"]["points"].items()}
        reflect = _midline_reflection(now, {"3.5", "3.6"})
        at = _centre(page, "front", "3.5")
        page.mouse.move(*at)
        page.mouse.down()
        page.mouse.move(at[0] + 12, at[1] - 9, steps=4)
        page.mouse.up()
        left = _point(page, "front", "3.5")
        assert np.allclose(left, now["3.5"] + np.array([12, -9]) / scale, atol=0.05)
        assert np.allclose(_point(page, "front", "3.6"), reflect(left), atol=0.05)
        page.keyboard.press("Control+z")  # one step undoes both
        for i in ("3.5", "3.6"):
            assert np.allclose(_point(page, "front", i), now[i])
        page.keyboard.press("m")

        # The checklist: N goes to the first point to check, Enter marks it checked.
        page.keyboard.press("n")
        first = page.evaluate("() => annotate.store.selected")
        assert page.locator("ol.checklist li.selected").count() == 1
        before = page.evaluate(f"() => annotate.store.confidence('{first['view']}', '{first['id']}')")
        assert before is not None and before < 0.5  # a guess (0) or an unsure automatic point
        page.keyboard.press("Enter")
        assert page.evaluate(f"() => annotate.store.confidence('{first['view']}', '{first['id']}')") is None
        page.keyboard.press("Control+z")
        assert page.evaluate(f"() => annotate.store.confidence('{first['view']}', '{first['id']}')") == before

        # Save, and read the file back.
        page.keyboard.press("Control+s")
        page.wait_for_function("() => document.getElementById('file-status').textContent.includes(': saved')",
                               timeout=10000)
        saved = read_fdp_json(fdp)
        assert np.allclose(saved.views["front"].points["9.3"], moved, atol=0.05)
        assert np.allclose(saved.views["front"].points["9.3"], _point(page, "front", "9.3"), atol=1e-6)
        assert "9.3" not in saved.views["front"].confidence  # moved by hand
        assert abs(saved.views["front"].confidence["3.5"] - conf_35) < 1e-8  # still the first guess
        assert np.allclose(saved.views["front"].points["3.6"], now["3.6"], atol=1e-6)
        assert saved.views["side"].points.keys() == state["side"].keys()
        # Photos in another folder than the file are named by their absolute path.
        assert json.loads(fdp.read_text())["views"]["front"]["image"] == str(photos[0].resolve())
        assert saved.views["front"].width == 1024 and saved.views["front"].height == 1280

        # Reload: the page comes back with the saved points and a fresh history.
        page.reload()
        page.wait_for_selector("body[data-ready=true]", timeout=20000)
        assert np.allclose(_point(page, "front", "9.3"), saved.views["front"].points["9.3"], atol=1e-6)
        assert page.is_disabled("#btn-undo")

        # The 3D preview fits points whose heights disagree between the photos, and says
        # that the build would refuse them...
        page.click("#btn-fit")
        page.wait_for_function("() => document.getElementById('preview3d').dataset.fits === '1'", timeout=60000)
        assert re.search(r"recon build would refuse these points: the heights of the points marked in both photos "
                         r"disagree: 9\.3 by \+\d+\.\d mm", page.inner_text("#preview-info"))
        # ... until the side photo's nose tip is dragged onto the same-height line.
        now = {v: {i: np.array(p) for i, p in pts["points"].items()} for v, pts in _points(page).items()}
        row = _height_map(now["front"], now["side"], {"9.3"})(now["front"]["9.3"])
        s_scale, _, _ = _view(page, "side")
        at = _centre(page, "side", "9.3")
        page.mouse.move(*at)
        page.mouse.down()
        page.mouse.move(at[0], at[1] + (row - now["side"]["9.3"][1]) * s_scale, steps=4)
        guide_row = (float(side_guides.get_attribute("y1")) - _view(page, "side")[2]) / s_scale
        assert guide_row == pytest.approx(row, abs=0.05)
        page.mouse.up()
        assert _point(page, "side", "9.3")[1] == pytest.approx(row, abs=0.05)
        # The preview refits after the change by itself, without the warning.
        page.wait_for_function("() => document.getElementById('preview3d').dataset.fits === '2'", timeout=60000)
        assert page.inner_text("#preview-info").startswith("Fitted in"), page.inner_text("#preview-info")
        assert "would refuse" not in page.inner_text("#preview-info")
        assert page.get_attribute("#head-view", "data-meshes") == "8"
        assert page.inner_text("#preview-info").startswith("Fitted in")
        png = page.evaluate("() => document.querySelector('#head-view canvas').toDataURL('image/png')")
        import base64

        pixels = np.asarray(Image.open(io.BytesIO(base64.b64decode(png.split(",", 1)[1]))).convert("RGB")).astype(int)
        background = np.array([0xf4, 0xf4, 0xf4])
        assert np.mean(np.abs(pixels - background).sum(axis=2) > 30) > 0.05  # the head covers part of the view
        page.screenshot(path=ARTIFACTS / "annotate_preview.png")

        # G: the points still guessed follow those placed by hand (the generic head refitted).
        from recon.annotate.placement import fit_view, generic_layout, shown_in

        before = _points(page)["front"]
        hand = {i: np.array(p) for i, p in before["points"].items() if i not in before["confidence"]}
        page.keyboard.press("g")
        page.wait_for_function("() => annotate.store.undoStack.at(-1)?.label === 'place guesses'", timeout=10000)
        layout = {i: generic_layout()["front"][i] for i in shown_in("front")}
        expected = fit_view(layout, hand, tuple(page.evaluate("() => annotate.sizes.front")))
        after = _points(page)["front"]["points"]
        guessed = [i for i in after if i not in hand]
        assert len(guessed) == 71 and sorted(hand) == ["9.3"]
        assert max(np.linalg.norm(after[i] - expected(layout[i])[0]) for i in guessed) < 1e-6
        page.keyboard.press("Control+z")

        # Zoom about the cursor keeps the point under it; dragging the background pans.
        at = _centre(page, "front", "2.1")
        scale = _view(page, "front")[0]
        page.mouse.move(*at)
        page.mouse.wheel(0, -300)
        page.wait_for_function(f"() => annotate.views.front.scale > {scale * 1.2}")
        assert np.allclose(_centre(page, "front", "2.1"), at, atol=0.5)
        s0, tx0, ty0 = _view(page, "front")
        page.mouse.move(at[0] + 60, at[1] + 120)
        page.mouse.down()
        page.mouse.move(at[0] + 10, at[1] + 90, steps=3)
        page.mouse.up()
        assert np.allclose(np.array(_view(page, "front")) - [s0, tx0, ty0], [0, -50, -30], atol=1e-6)
        page.keyboard.press("f")
        assert _view(page, "front")[0] == pytest.approx(scale)
        assert errors == []
    finally:
        annotate_cli.stop(proc)
    assert proc.returncode == 0, proc.stderr.read()


def test_the_page_shows_the_side_facing_and_turns_the_side_round(photos, browser, tmp_path, annotate_cli):
    pytest.importorskip("mediapipe")
    proc, url = annotate_cli.start(*photos, "--fdp", tmp_path / "t.fdp.json")
    try:
        page, errors = _open(browser, url, timeout=30000)
        shown = page.inner_text("#side-facing")
        assert "nose points left" in shown and "confidence" in shown, shown
        before = {i: np.array(p) for i, p in _points(page)["side"]["points"].items()}
        ear = lambda pts: np.mean([p[0] for i, p in pts.items() if i.startswith("10.")])  # noqa: E731
        assert before["9.3"][0] < ear(before)

        page.keyboard.press("t")
        page.wait_for_selector("#side-facing[data-facing=right]", timeout=30000)
        assert "turned round by you" in page.inner_text("#side-facing")
        after = {i: np.array(p) for i, p in _points(page)["side"]["points"].items()}
        assert after["9.3"][0] > ear(after)
        page.screenshot(path=ARTIFACTS / "annotate_turned.png")

        page.keyboard.press("Control+z")  # one undo turns them back
        back = {i: np.array(p) for i, p in _points(page)["side"]["points"].items()}
        assert set(back) == set(before) and all(np.allclose(back[i], before[i]) for i in before)
        assert not errors, errors
    finally:
        annotate_cli.stop(proc)
