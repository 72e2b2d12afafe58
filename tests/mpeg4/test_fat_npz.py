"""The compact FAT file: round trip, quantisation bound, bad files."""

import numpy as np
import pytest

from mpeg4 import InputError, apply_fat
from mpeg4.fapu import FAPU
from mpeg4.fat import FAT, FaceDefMesh, FaceDefTable, FaceDefTransform
from mpeg4.io.fat_npz import fat_npz_bytes, quantisation_error, read_fat_npz, write_fat_npz

FAPU_ = FAPU(IRISD0=0.01, ES0=0.065, ENS0=0.045, MNS0=0.02, MW0=0.05)


def _fat():
    rng = np.random.default_rng(3)
    fat = FAT()
    fat.add(FaceDefTable(3, meshes=[FaceDefMesh("skin", [0, 512, 1024], [2, 5, 900, 901],
                                                rng.normal(size=(4, 2, 3)) * 0.02)]))
    fat.add(FaceDefTable(19, meshes=[FaceDefMesh("skin", [-512, 0, 512], [7, 8], rng.normal(size=(2, 2, 3)) * 0.5),
                                     FaceDefMesh("eye_l", [-512, 0, 512], [0], rng.normal(size=(1, 2, 3)))]))
    fat.add(FaceDefTable(49, transforms=[FaceDefTransform(None, "rotation", [0, -0.02, -0.01], [0, 1, 0], 1.0)]))
    fat.add(FaceDefTable(27, transforms=[FaceDefTransform("eye_l", "translation", amount=[0, 0, 1])]))
    fat.add(FaceDefTable(1, 10, meshes=[FaceDefMesh("skin", [0, 63], [1, 3], rng.normal(size=(2, 1, 3)) * 0.01)]))
    fat.add(FaceDefTable(2, 0))
    return fat


def test_round_trip_within_the_stated_bound(tmp_path):
    fat = _fat()
    path = write_fat_npz(fat, tmp_path / "t.fat.npz")
    back = read_fat_npz(path)
    assert sorted(back) == sorted(fat)
    bound = quantisation_error(fat, FAPU_)
    assert 0 < bound < 1e-5
    neutral = {"skin": np.zeros((1000, 3)), "eye_l": np.ones((3, 3))}
    for values in ({3: 700.0}, {3: 256.0, 19: -300.0}, {19: 512.0}, {(1, 10): 63.0, 49: 5000.0, 27: 40.0}):
        a = apply_fat(fat, neutral, values, FAPU_)
        b = apply_fat(back, neutral, values, FAPU_)
        err = max(np.abs(a[k] - b[k]).max() for k in a)
        assert err <= 2 * bound, values  # two tables active at most
    for key in fat:
        for m, n in zip(fat[key].meshes, back[key].meshes):
            np.testing.assert_array_equal(m.indices, n.indices)
            np.testing.assert_array_equal(m.borders, n.borders)
        for s, t in zip(fat[key].transforms, back[key].transforms):
            assert s.part == t.part and s.kind == t.kind
            np.testing.assert_array_equal(s.centre, t.centre)


def test_same_tables_same_bytes():
    assert fat_npz_bytes(_fat()) == fat_npz_bytes(_fat())


def test_bad_files_are_named(tmp_path):
    with pytest.raises(InputError, match="FAT file not found"):
        read_fat_npz(tmp_path / "none.npz")
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a zip")
    with pytest.raises(InputError, match="junk.npz: not a readable FAT file"):
        read_fat_npz(junk)
    other = tmp_path / "other.npz"
    np.savez(other, header=np.frombuffer(b'{"format": "x", "version": 1, "tables": []}', dtype=np.uint8))
    with pytest.raises(InputError, match="format is 'x'"):
        read_fat_npz(other)
