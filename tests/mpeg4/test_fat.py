import numpy as np
import pytest
from hypothesis import given, strategies as st

from mpeg4 import FAPU, InputError
from mpeg4.fat import (
    FAT, FaceDefMesh, FaceDefTable, FaceDefTransform, apply_fat, fat_from_morph_targets, fat_to_morph_targets,
    morph_weights, rotation_matrix, signed_overlaps,
)
from mpeg4.head import Head, Part

FAPU_ = FAPU(IRISD0=0.011, ES0=0.064, ENS0=0.042, MNS0=0.017, MW0=0.05)


def test_worked_example_of_section_5():
    # Borders [-400, 0, 300, 900]; displacements (0,1,0), (0,2,0), (0,0.5,1).
    m = FaceDefMesh("skin", [-400, 0, 300, 900], [7], [[[0, 1, 0], [0, 2, 0], [0, 0.5, 1]]])
    np.testing.assert_array_equal(m.offsets(500, 1.0), [[0, 700, 200]])
    np.testing.assert_array_equal(m.offsets(-100, 1.0), [[0, -100, 0]])
    np.testing.assert_array_equal(m.offsets(0, 1.0), [[0, 0, 0]])
    # And scaled by the FAP unit.
    np.testing.assert_allclose(m.offsets(500, FAPU_.unit("MNS")), [[0, 700 * 0.017 / 1024, 200 * 0.017 / 1024]])


def test_values_beyond_the_borders_extend_the_outer_slopes():
    m = FaceDefMesh("skin", [-400, 0, 300, 900], [0], [[[0, 1, 0], [0, 2, 0], [0, 0.5, 1]]])
    # 1500 = 300 * (0,2,0) + 1200 * (0,0.5,1): the last slope continues past 900.
    np.testing.assert_array_equal(m.offsets(1500, 1.0), [[0, 1200, 1200]])
    np.testing.assert_array_equal(m.offsets(-1000, 1.0), [[0, -1000, 0]])
    # A table defined on one side of 0 only does not move on the other side.
    u = FaceDefMesh("skin", [0, 1024], [0], [[[0, -1, 0]]])
    np.testing.assert_array_equal(u.offsets(-300, 1.0), [[0, 0, 0]])
    np.testing.assert_array_equal(u.offsets(2048, 1.0), [[0, -2048, 0]])


@given(st.lists(st.floats(-2000, 2000, allow_nan=False), min_size=2, max_size=6, unique=True),
       st.floats(-3000, 3000, allow_nan=False))
def test_overlaps_are_continuous_and_sum_to_the_value(borders, value):
    b = np.sort(np.array(borders + [0.0]))
    if (np.diff(b) <= 1e-6).any():
        return
    s = signed_overlaps(b, value)
    # The pieces of [0, P] tile it exactly, so they sum to P, on a side of 0 the table
    # defines; on an undefined side nothing moves.
    defined = b[0] < 0 if value < 0 else b[-1] > 0
    assert s.sum() == pytest.approx(value if defined else 0.0, abs=1e-6)
    assert (np.sign(s[s != 0]) == np.sign(value)).all()


def test_superposition_and_transforms():
    verts = {"skin": np.zeros((3, 3)), "eye_l": np.array([[0.0, 0.0, 0.01], [0.0, 0.0, 0.0]])}
    fat = FAT()
    fat.add(FaceDefTable(3, 0, [FaceDefMesh("skin", [0, 1024], [0, 1], [[[0, -1, 0]], [[0, -0.5, 0]]])]))
    fat.add(FaceDefTable(51, 0, [FaceDefMesh("skin", [-100, 0, 1024], [1], [[[0, -2, 0], [0, -1, 0]]])]))
    fat.add(FaceDefTable(23, 0, transforms=[FaceDefTransform("eye_l", "rotation", centre=[0, 0, 0], axis=[0, 1, 0])]))
    out = apply_fat(fat, verts, {3: 512, 51: 200, 23: 157080}, FAPU_)
    mns = FAPU_.unit("MNS")
    np.testing.assert_allclose(out["skin"][0], [0, -512 * mns, 0])
    np.testing.assert_allclose(out["skin"][1], [0, -256 * mns - 200 * mns, 0])  # the two FAPs add up
    np.testing.assert_allclose(out["skin"][2], [0, 0, 0])
    # yaw of 1.5708 rad (FAP value 157080 AU) turns the gaze (+z) to the face's left (+x).
    np.testing.assert_allclose(out["eye_l"][0], [0.01, 0, 0], atol=1e-6)
    # Inputs untouched.
    assert not verts["skin"].any()


def test_head_rotation_applies_to_every_part_last():
    verts = {"skin": np.array([[0.0, 0.1, 0.0]]), "eye_l": np.array([[0.0, 0.0, 0.1]])}
    fat = FAT()
    fat.add(FaceDefTable(50, 0, transforms=[FaceDefTransform(None, "rotation", centre=[0, 0, 0], axis=[0, 0, 1])]))
    fat.add(FaceDefTable(23, 0, transforms=[FaceDefTransform("eye_l", "rotation", centre=[0, 0, 0], axis=[0, 1, 0])]))
    out = apply_fat(fat, verts, {50: np.pi / 2 * 1e5, 23: np.pi / 2 * 1e5}, FAPU_)
    np.testing.assert_allclose(out["skin"][0], [-0.1, 0, 0], atol=1e-9)  # top of the head tilts to -x
    # The eye first yaws to +x, then the whole head rolls: +x goes to +y.
    np.testing.assert_allclose(out["eye_l"][0], [0, 0.1, 0], atol=1e-9)


def test_rotation_matrix_is_right_handed():
    np.testing.assert_allclose(rotation_matrix([0, 1, 0], np.pi / 2) @ [0, 0, 1], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(rotation_matrix([1, 0, 0], np.pi / 2) @ [0, 0, 1], [0, -1, 0], atol=1e-12)


def _random_fat(rng):
    fat = FAT()
    for fap, borders in [(3, [0, 300, 1024]), (4, [-400, 0, 300, 900]), (31, [-512, 512]), (19, [0, 1024])]:
        n = len(borders) - 1
        meshes = [FaceDefMesh(part, borders, idx, rng.normal(size=(len(idx), n, 3)))
                  for part, idx in [("skin", rng.choice(50, 12, replace=False)), ("teeth", [0, 2])]]
        fat.add(FaceDefTable(fap, 0, meshes))
    fat.add(FaceDefTable(2, 1, [FaceDefMesh("skin", [0, 63], [1, 2, 3], rng.normal(size=(3, 1, 3)))]))
    fat.add(FaceDefTable(23, 0, transforms=[FaceDefTransform("eye", "rotation", centre=[0, 0, 0.1], axis=[0, 1, 0])]))
    return fat


def test_fat_to_morph_targets_to_fat_round_trip():
    rng = np.random.default_rng(0)
    verts = {"skin": rng.normal(size=(50, 3)), "teeth": rng.normal(size=(4, 3)), "eye": rng.normal(size=(5, 3))}
    fat = _random_fat(rng)
    targets, specs = fat_to_morph_targets(fat, FAPU_)
    assert "open_jaw[0,300]" in targets and "expression_joy" in targets and "raise_l_i_eyebrow-" in targets
    back = fat_from_morph_targets(targets, specs, FAPU_, transforms=fat)
    assert set(back) == set(fat)
    for key, table in fat.items():
        for m in table.meshes:
            mb = next(x for x in back[key].meshes if x.part == m.part)
            # Borders gain a split at 0; evaluate the tables instead of comparing storage.
            for value in (-900, -400, -1, 0, 1, 150, 300, 700, 1024, 2500):
                np.testing.assert_allclose(mb.offsets(value, 1.0)[np.searchsorted(mb.indices, m.indices)],
                                           m.offsets(value, 1.0), atol=1e-12)
        assert len(back[key].transforms) == len(table.transforms)
    # The morph targets with morph_weights reproduce apply_fat exactly (mesh part).
    head = Head({n: Part(n, v, np.zeros((0, 3), int)) for n, v in verts.items()}, morph_targets=targets)
    for values in ({3: 700, 4: -250, 31: 1000}, {4: 2000, 19: -50, (2, 1): 40}):
        want = apply_fat(fat, verts, values, FAPU_)
        got = head.morphed(morph_weights(specs, values))
        for n in ("skin", "teeth"):
            np.testing.assert_allclose(got[n], want[n], atol=1e-12)


def test_bad_tables_are_rejected():
    with pytest.raises(InputError, match="not strictly increasing"):
        FaceDefMesh("skin", [0, 0, 10], [0], np.zeros((1, 2, 3)))
    with pytest.raises(InputError, match="do not contain 0"):
        FaceDefMesh("skin", [10, 20], [0], np.zeros((1, 1, 3)))
    with pytest.raises(InputError, match="not a viseme"):
        FaceDefTable(1, 15)
    with pytest.raises(InputError, match="unknown FAP"):
        FaceDefTable(70)
