"""The real-photo benchmark runs through on two people and prints every figure."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAIRS = ROOT.parent / "shared" / "data" / "real_photos" / "pairs"
FIGURES = ("built", "point_agreement_ipd_pct", "profile_line_ipd_pct", "silhouette_iou_front", "silhouette_iou_side",
           "heldout_profile_line_ipd_pct", "heldout_silhouette_iou", "identity_distance", "identity_distance_lights",
           "identity_distance_other_people", "skin_delta_e", "skin_delta_e_relit", "skin_delta_e_worst")


@pytest.mark.skipif(not PAIRS.exists(), reason=f"the real photo pairs are not there ({PAIRS})")
def test_two_people_smoke_run_prints_every_figure(tmp_path):
    pytest.importorskip("mediapipe")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "real_photos.py"), "--people", "2",
                          "--texture-size", "512", "--sheet", str(tmp_path / "sheet.png")],
                         capture_output=True, text=True, timeout=600, env=env, cwd=ROOT)
    assert out.returncode == 0, out.stderr[-2000:]
    lines = dict(line.split(": ", 1) for line in out.stdout.splitlines() if ": " in line and not line.startswith("#"))
    missing = [f for f in FIGURES if f not in lines]
    assert not missing, out.stdout
    assert lines["built"].endswith("of 2")
    assert (tmp_path / "sheet.png").exists()
