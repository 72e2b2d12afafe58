"""Shared fixtures: the Khronos glTF validator, the ICT FaceKit test data, whether the mesh
marking's 2D detector is installed, the notebooks' report."""

import json
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ICT_NPZ = ROOT.parent / "shared" / "data" / "ict_facekit" / "ict_facekit.npz"


@pytest.fixture(scope="session")
def validate_gltf():
    """A function path → Khronos validator report (dict); skips when the validator is absent."""
    node = shutil.which("node")
    if node is None or not (ROOT / "node_modules" / "gltf-validator").is_dir():
        pytest.skip("the Khronos glTF validator is not installed (run: npm ci)")

    def run(path):
        out = subprocess.run([node, str(ROOT / "tests" / "gltf_validate.js"), str(path)], cwd=ROOT,
                             capture_output=True, text=True, timeout=120)
        assert out.returncode == 0, out.stderr
        return json.loads(out.stdout)

    return run


@pytest.fixture(scope="session")
def landmark_detector_available() -> bool:
    """Whether ``fmc mark`` has its 2D detector here (recon.landmarks with mediapipe)."""
    from mpeg4.errors import InputError
    from recon.mark import landmark_detector

    try:
        landmark_detector()
    except InputError:
        return False
    return True


@pytest.fixture(scope="session")
def ict_npz():
    """Path of the ICT FaceKit data; skips when ../shared/data is absent."""
    if not ICT_NPZ.exists():
        pytest.skip(f"ICT FaceKit test data not found at {ICT_NPZ}")
    return ICT_NPZ


@pytest.fixture(scope="session")
def remeshed(ict_npz, tmp_path_factory):
    """A function (seed, fmt) -> recon.evaluate.synthetic.MeshFile, each made once per test run."""
    pytest.importorskip("fast_simplification", reason="fast-simplification is not installed (pip install '.[test]')")
    from recon.evaluate.synthetic import load_ict, remeshed_identity

    cache = {}

    def get(seed, fmt):
        if (seed, fmt) not in cache:
            cache[seed, fmt] = remeshed_identity(seed, tmp_path_factory.mktemp(f"remeshed{seed}"), load_ict(ict_npz),
                                                 fmt=fmt)
        return cache[seed, fmt]

    return get


_NOTEBOOK_LINES = pytest.StashKey[list]()


@pytest.fixture
def notebook_report(request):
    """A list to append lines to; they are printed in a "notebooks" section at the end of
    the run, so the log shows every notebook that was executed and how long it took."""
    return request.config.stash.setdefault(_NOTEBOOK_LINES, [])


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    lines = config.stash.get(_NOTEBOOK_LINES, [])
    if lines:
        terminalreporter.section("notebooks")
        for line in lines:
            terminalreporter.write_line(line)
