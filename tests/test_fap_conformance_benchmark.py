"""The FAP conformance benchmark plays a real Xface stream on the generic head and prints
every figure; parts stay parts there."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
STREAMS = ROOT.parent / "shared" / "data" / "fap_streams"
FIGURES = ("eyeball_centre_shift_max_mm", "fp_conformance_pct", "inverted_triangles_max", "edge_stretch_max",
           "lid_overlap_max_mm", "region_over_fp_max")


@pytest.mark.skipif(not (STREAMS / "xface").exists(), reason=f"the real FAP streams are not there ({STREAMS})")
def test_a_real_stream_prints_every_figure(tmp_path):
    shutil.copy(STREAMS / "xface" / "test.fap", tmp_path / "test.fap")  # test data, in a temporary folder only
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "fap_conformance.py"), str(tmp_path),
                          "--heads", "generic"], capture_output=True, text=True, timeout=600, env=env, cwd=ROOT)
    assert out.returncode == 0, out.stderr[-2000:]
    lines = dict(line.split(": ", 1) for line in out.stdout.splitlines() if ": " in line)
    missing = [f for f in FIGURES if f"generic.{f}" not in lines or f"generic.test.{f}" not in lines]
    assert not missing, out.stdout
    assert float(lines["generic.eyeball_centre_shift_max_mm"]) <= 0.2
    assert 0.0 <= float(lines["generic.fp_conformance_pct"]) <= 100.0
