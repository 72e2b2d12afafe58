"""The generic head's stored Facial Animation Tables equal a fresh authoring."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from mpeg4 import InputError, apply_fat
from mpeg4.generic_head import GENERIC_HEAD_DIR, load_generic_head
from mpeg4.io.fat_npz import quantisation_error

ROOT = Path(__file__).resolve().parents[1]


def _builder():
    spec = importlib.util.spec_from_file_location("build_generic_fat", ROOT / "scripts" / "build_generic_fat.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_committed_fat_equals_a_fresh_build():
    shipped = load_generic_head(with_fat=True)
    fresh, _ = _builder().build_generic_fat(load_generic_head())
    assert sorted(shipped.fat) == sorted(fresh)
    assert len(fresh) == 66 + 15 + 7
    bound = quantisation_error(fresh, shipped.fapu)
    assert bound < 5e-6
    neutral = {n: p.vertices for n, p in shipped.parts.items()}
    for values in ({3: 512.0}, {3: 1000.0, 12: -300.0}, {(1, 10): 63.0}, {(2, 1): 63.0}, {31: 512.0, 19: -400.0},
                   {49: 20000.0, 23: -5000.0, 53: 300.0}, {29: 512.0, 47: 200.0, 65: -512.0}):
        a = apply_fat(fresh, neutral, values, shipped.fapu)
        b = apply_fat(shipped.fat, neutral, values, shipped.fapu)
        assert max(np.abs(a[k] - b[k]).max() for k in a) <= len(values) * bound + 1e-9, values


def test_committed_files_fit_the_budget():
    total = sum(p.stat().st_size for p in GENERIC_HEAD_DIR.glob("generic_head*"))
    assert total <= 15e6, total


def test_missing_tables_say_how_to_rebuild(tmp_path, monkeypatch):
    import shutil

    shutil.copy(GENERIC_HEAD_DIR / "generic_head.glb", tmp_path / "other.glb")
    monkeypatch.setenv("MPEG4_GENERIC_HEAD", str(tmp_path / "other.glb"))
    assert load_generic_head().fat is None
    with pytest.raises(InputError, match=r"other_fat.npz: the generic head's animation tables are missing.*"
                                         r"build_generic_fat.py"):
        load_generic_head(with_fat=True)
