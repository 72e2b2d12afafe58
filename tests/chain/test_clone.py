"""fmc clone onto a head mesh without feature points: marked first, with a warning."""

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("fast_simplification", reason="fast-simplification is not installed (pip install '.[test]')")

from chain import clone_onto, target_head  # noqa: E402
from mpeg4.generic_head import generic_head_path  # noqa: E402
from recon.mark import mark_file  # noqa: E402
from recon.evaluate.synthetic import perfect_detector  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def mesh(remeshed):
    return remeshed(7, "obj")


@pytest.mark.slow
def test_clone_onto_an_unmarked_mesh(mesh):
    head, warnings = clone_onto(generic_head_path(), mesh.path, detect=perfect_detector(mesh.points))
    assert "unreviewed" in warnings[0] and "fmc mark" in warnings[0]
    assert len(head.morph_targets) == 55 and {"skin", "eye_l", "tongue"} <= set(head.parts)
    # The cloned jaw opens the target's mouth: the chin goes down and back by about what it
    # does on the generic head (the two faces are of a size).
    moved = head.fp_position("2.1", head.morphed({"jawOpen": 1.0})) - head.fp_position("2.1")
    assert moved[1] < -0.015 and moved[2] < -0.01 and abs(moved[0]) < 0.002
    # Eyes turn about their own centres, which marking found.
    assert np.linalg.norm(head.parts["eye_l"].centre - head.fp_position("3.5")) < 0.02


def test_marked_but_unreviewed_points_are_said_so(mesh, tmp_path):
    path = tmp_path / mesh.path.name
    path.write_bytes(mesh.path.read_bytes())
    mark_file(path, detect=perfect_detector(mesh.points), passes=1)
    head, warnings = target_head(path, detect=lambda v: pytest.fail("the saved points are used"))
    assert len(warnings) == 1 and "not reviewed" in warnings[0] and "recon annotate" in warnings[0]
    assert "2.1" in head.feature_points


def test_clone_onto_an_unmarked_mesh_without_a_detector_is_one_line(mesh, tmp_path, landmark_detector_available):
    import os
    import subprocess
    import sys

    if landmark_detector_available:
        pytest.skip("recon.landmarks and mediapipe are installed: the target would be marked")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-m", "chain", "clone", "--source", str(generic_head_path()), "--target",
                          str(mesh.path), "-o", str(tmp_path / "out.glb")], capture_output=True, text=True, env=env,
                         cwd=tmp_path)
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert "no 2D landmark detector" in out.stderr and "recon annotate" in out.stderr




def test_the_generic_head_is_the_default_source_with_its_tables(tmp_path):
    """``fmc clone --target T -o OUT`` clones the generic head's tables; naming its GLB as the
    source finds the tables stored beside it."""
    from typer.testing import CliRunner

    from fmc.heads import animated_head
    from fmc.cli import app
    from mpeg4.generic_head import load_generic_head
    from mpeg4.io import load_head, save_head

    generic = load_generic_head(with_fat=True)
    assert len(animated_head(None).fat) == len(generic.fat) == len(animated_head(generic_head_path()).fat) >= 88
    target = generic.with_vertices({k: p.vertices * 0.95 for k, p in generic.parts.items()})
    target.morph_targets, target.fat = {}, None
    save_head(target, tmp_path / "tgt.glb")
    out = CliRunner().invoke(app, ["clone", "--target", str(tmp_path / "tgt.glb"), "-o", str(tmp_path / "out.glb")])
    assert out.exit_code == 0, out.output
    head = load_head(tmp_path / "out.glb")
    assert head.fat is not None and len(head.fat) == len(generic.fat)
