"""Facial motion cloning: exact on itself, FAPU-compliant on another head, clear errors."""

import numpy as np
import pytest

from fmc.clone import clone, clone_targets
from mpeg4 import FAPS, InputError, apply_fat
from mpeg4.fat import fap_unit
from mpeg4.generic_head import load_generic_head


def _pyun_error(cloned, truth, n_vertices):
    """Sum of vertex position errors over the sum of displacement norms, in per cent."""
    c = cloned["skin"].dense(n_vertices)
    g = truth["skin"].dense(n_vertices)
    return 100 * np.linalg.norm(c - g, axis=1).sum() / np.linalg.norm(g, axis=1).sum()


def test_cloning_a_head_onto_itself_is_exact():
    head = load_generic_head()
    names = ["jawOpen", "mouthSmile_L", "browInnerUp_L", "eyeBlink_R", "mouthPucker", "noseSneer_L"]
    cloned = clone_targets(head, head, names)
    n = head.skin.n_vertices
    errors = [_pyun_error(cloned[k], head.morph_targets[k], n) for k in names]
    assert max(errors) <= 0.05  # per cent


def test_cloned_fat_is_fapu_compliant_on_a_different_head(authored_head, ict_npz):
    import importlib.util
    from pathlib import Path

    spec = importlib.util.spec_from_file_location(
        "shape_accuracy", Path(__file__).resolve().parents[2] / "benchmarks" / "shape_accuracy.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    target = load_generic_head()
    target = target.with_vertices(bench.part_vertices(target, bench.identity_vertices(np.load(ict_npz),
                                                                                       np.random.default_rng(7))))
    target.morph_targets = {}
    out, warnings = clone(authored_head, target)
    assert not warnings and len(out.fat) == len(authored_head.fat)
    errs = []
    for n in (3, 5, 12, 19, 31, 33, 41, 52, 59):  # skin FAPs of the mouth, lids, brows, cheeks
        fp = FAPS[n].feature_points[0]

        def per_unit(h):
            moved = apply_fat(h.fat, {k: p.vertices for k, p in h.parts.items()}, {n: 256.0}, h.fapu)
            return (h.fp_position(fp, moved) - h.fp_position(fp)) / fap_unit(n, h.fapu)

        a, b = per_unit(authored_head), per_unit(out)
        errs.append(np.linalg.norm(a - b) / np.linalg.norm(a))
    assert np.median(errs) < 0.10


def test_bad_input():
    head = load_generic_head()
    bare = head.copy()
    del bare.feature_points["8.3"]
    with pytest.raises(InputError, match="the target head lacks the feature points 8.3"):
        clone_targets(head, bare)
    still = head.copy()
    still.morph_targets = {}
    with pytest.raises(InputError, match="no morph targets or animation tables to clone"):
        clone(still, head)
