"""Start-up time of ``recon annotate``: from the command's start to the page showing the
pre-placed points, and the 3D preview's fit on demand.

The example photos (``data/example/``, or two given with ``--photos``) are opened with
``python -m recon annotate FRONT SIDE --no-browser`` and a new annotation file;
Debian's Chromium, already running (as a user's browser is), opens the printed address as
soon as it appears. Times are from starting the command:

- ``server_ready``: the address printed (the server listens);
- ``points_shown``: the page has drawn the pre-placed points on both views;
- ``photos_shown``: both photos are decoded and drawn as well (the page is usable);
- ``fit_preview``: from asking for the 3D preview to the fitted head drawn (with the
  example's person and lens, ``--ipd 69.16 --focal 5333.33``, as ``recon build`` is run
  on it; photos taken close up disagree in the heights of points far from the middle by
  more than the fit accepts when it assumes orthographic photos).

Run: ``python3 benchmarks/annotate_startup.py [--runs 3] [--photos FRONT SIDE]``. Prints
``name: value unit`` lines, the last a summary (target: under 3 s to the points).
"""

from __future__ import annotations

import argparse
import os
import select
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CHROMIUM = "/usr/bin/chromium"
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--no-first-run"]
TARGET_S = 3.0
#: The example photos' person and lens (``data/example/README.md``), as ``recon build`` is given them.
EXAMPLE_IPD_MM = 69.16
EXAMPLE_FOCAL_PX = 5333.33


def _run(browser, photos: list[Path], fdp: Path, fit: bool, camera: list[str]) -> dict[str, float]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "recon", "annotate", *map(str, photos), "--fdp", str(fdp),
                             "--no-browser", *camera], cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        if not select.select([proc.stdout], [], [], 60)[0]:
            raise RuntimeError("recon annotate printed nothing in 60 s")
        line = proc.stdout.readline()
        if not line.startswith("annotate: "):
            raise RuntimeError(f"recon annotate did not start: {line!r} {proc.stderr.read()}")
        out = {"server_ready": time.perf_counter() - t0}
        page = browser.new_page(viewport={"width": 1400, "height": 860})
        page.goto(line.split(" ", 1)[1].strip(), wait_until="commit")
        page.wait_for_selector('body[data-points="shown"] svg.photo[data-view="side"] .pt', timeout=60000)
        out["points_shown"] = time.perf_counter() - t0
        page.wait_for_selector("body[data-ready=true]", timeout=60000)
        out["photos_shown"] = time.perf_counter() - t0
        out["points"] = page.locator(".pt").count()
        if fit:
            t1 = time.perf_counter()
            page.click("#btn-fit")
            page.wait_for_function("() => document.getElementById('preview3d').dataset.fits === '1'"
                                   " || document.getElementById('preview-info').textContent.startsWith('No fit')",
                                   timeout=120000)
            out["fit_preview"] = time.perf_counter() - t1
            out["fit_info"] = page.locator("#preview-info").text_content()
        page.close()
        return out
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--photos", nargs=2, type=Path, metavar=("FRONT", "SIDE"),
                        default=[ROOT / "data" / "example" / "front.jpg", ROOT / "data" / "example" / "side.jpg"])
    parser.add_argument("--ipd", type=float, default=None, help="mm (default: the example's, 69.16, for its photos)")
    parser.add_argument("--focal", type=float, default=None,
                        help="pixels (default: the example's lens, 5333.33, for its photos)")
    args = parser.parse_args()
    example = all(p.resolve().parent == (ROOT / "data" / "example").resolve() for p in args.photos)
    ipd = args.ipd if args.ipd is not None else (EXAMPLE_IPD_MM if example else None)
    focal = args.focal if args.focal is not None else (EXAMPLE_FOCAL_PX if example else None)
    camera = [*(["--ipd", str(ipd)] if ipd else []), *(["--focal", str(focal)] if focal else [])]
    if not os.path.exists(CHROMIUM):
        print(f"skipped: Chromium not found at {CHROMIUM} (apt-get install chromium)")
        return 0
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory() as tmp, sync_playwright() as p:
        tmp = Path(tmp)
        photos = [p.resolve() for p in args.photos]
        browser = p.chromium.launch(executable_path=CHROMIUM, args=FLAGS)
        runs = []
        for k in range(args.runs):
            runs.append(_run(browser, photos, tmp / f"run{k}.fdp.json", fit=(k == 0), camera=camera))
        browser.close()
    from PIL import Image

    sizes = ", ".join(f"{p.name} {Image.open(p).size[0]}x{Image.open(p).size[1]}" for p in photos)
    print(f"photos: {sizes} px")
    print(f"points_drawn: {runs[0]['points']} points")
    for key in ("server_ready", "points_shown", "photos_shown"):
        values = [r[key] for r in runs]
        print(f"{key}_median: {np.median(values):.2f} s (runs: {', '.join(f'{v:.2f}' for v in values)})")
    print(f"camera: {' '.join(camera) or 'orthographic, --ipd 63'}")
    print(f"fit_preview: {runs[0]['fit_preview']:.2f} s ({runs[0]['fit_info']})")
    median = float(np.median([r["points_shown"] for r in runs]))
    verdict = "meets" if median < TARGET_S else "misses"
    print(f"annotate_startup_to_points: {median:.2f} s ({verdict} the {TARGET_S:g} s target)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
