"""FATs authored by FaceEngine's hybrid muscle model, checked through the decoder."""

import numpy as np
import pytest

from mpeg4 import FAPS, FP_IDS, InputError, apply_fat
from mpeg4.catalogue import FEATURE_POINTS
from mpeg4.fat import fap_unit
from mpeg4.generic_head import load_generic_head
from fmc.author import JAW_FAPS, unrelated
from fmc.author import lip_side, smooth_partition
from fmc.lip_contours import LIP_NODES, innerness
from fmc.bound import bound_tables
from fmc.separate import separate_tables
from fmc.unfold import unfold_tables
from fmc.muscles import (GROUPS, HIGH_LEVEL_FAPS, Muscle, MuscleRig, author_from_muscles,
                         author_high_level_from_muscles, eyeball_centre, load_placement, place_muscles, split_lips)


def _bare_head():
    """The generic head without its sculpted shapes: only the feature points guide the model."""
    head = load_generic_head()
    head.morph_targets = {}
    return head


@pytest.fixture(scope="module")
def rigged():
    head = _bare_head()
    rig = MuscleRig.from_head(head)
    fat, report = author_from_muscles(head, rig=rig)
    fat.update(author_high_level_from_muscles(rig))
    head.fat = fat
    return head, rig, {r.fap: r for r in report}


def _fp_motion(head, values):
    neutral = {n: p.vertices for n, p in head.parts.items()}
    moved = apply_fat(head.fat, neutral, values, head.fapu)
    return {i: head.fp_position(i, moved) - head.fp_position(i) for i in head.feature_points}


# --- placement data ---------------------------------------------------------------------

def test_placement_data_loads_and_names_real_points():
    data = load_placement()
    assert {"jaw", "neck", "lids", "muscles"} <= set(data)
    kinds = {name[:-2] if name.endswith("_l") else name for name in data["muscles"]}
    assert len(kinds) >= 17  # the paper's set: 17+ kinds of muscle
    for name, spec in data["muscles"].items():
        assert spec["kind"] in ("linear", "sphincter"), name
        assert spec.get("group") is None or spec["group"] in GROUPS, name
        points = [spec["centre"]] if spec["kind"] == "sphincter" else [spec["head"], spec["tail"]]
        for p in points:
            assert set(p["at"]) <= set(FEATURE_POINTS) and abs(sum(p["at"].values()) - 1) < 1e-9, name


def test_muscles_are_placed_symmetrically_on_a_symmetric_head():
    muscles = {m.name: m for m in place_muscles(_bare_head())}
    assert len(muscles) >= 34
    for name, m in muscles.items():
        if name.endswith("_l"):
            r = muscles[name[:-2] + "_r"]
            np.testing.assert_allclose(r.head, m.head * [-1, 1, 1], atol=1e-4)
            assert r.group == (m.group[:-2] + "_r" if m.group and m.group.endswith("_l") else m.group)


# --- the Waters muscle ------------------------------------------------------------------

def _linear(**kw):
    args = dict(name="m", kind="linear", head=np.zeros(3), tail=np.array([0.0, -0.04, 0.0]), zone=np.radians(30),
                fall_start=0.04, fall_end=0.06, semi_axes=None, midline=0.0, elasticity=0.3, side="L", group=None,
                acts_on="all")
    args.update(kw)
    return Muscle(**args)


def test_linear_muscle_pulls_towards_its_head_with_both_falloffs():
    m = _linear()
    on_axis = np.array([[0.0, -y, 0.0] for y in (0.0, 0.02, 0.04, 0.05, 0.06, 0.07)])
    d = m.displacement(on_axis)
    assert np.allclose(d[:, [0, 2]], 0) and (d[1:4, 1] > 0).all()  # up, towards the head
    np.testing.assert_allclose(d[2, 1], 0.3 * 0.04)  # peak at the fall-off start: k · L
    assert d[0, 1] == 0 and abs(d[4, 1]) < 1e-12 and d[5, 1] == 0  # nothing at the head or beyond Rf
    np.testing.assert_allclose(d[1, 1], 0.3 * 0.04 * np.cos(0.5 * np.pi / 2))  # rising radial fall-off
    # Angular fall-off: cos(μ/zone · π/2) at 15° off the axis, nothing beyond 30°.
    p15 = 0.04 * np.array([[np.sin(np.radians(15)), -np.cos(np.radians(15)), 0.0]])
    p31 = 0.04 * np.array([[np.sin(np.radians(31)), -np.cos(np.radians(31)), 0.0]])
    np.testing.assert_allclose(np.linalg.norm(m.displacement(p15)), 0.3 * 0.04 * np.cos(np.pi / 4))
    assert not m.displacement(p31).any()


def test_sphincter_draws_in_within_its_ellipse_in_its_plane():
    m = _linear(kind="sphincter", tail=None, semi_axes=np.array([0.03, 0.01, 0.03]), elasticity=0.5, side="C")
    p = np.array([[0.0, 0.0, 0.0], [0.015, 0.0, 0.004], [0.0, 0.005, 0.0], [0.031, 0.0, 0.0]])
    d = m.displacement(p)
    assert not d[0].any() and not d[3].any()
    np.testing.assert_allclose(d[1], [-0.5 * (1 - np.hypot(0.5, 0.004 / 0.03)) * 0.015, 0, 0])
    np.testing.assert_allclose(d[2], [0, -0.5 * 0.5 * 0.005, 0])


def test_groups_take_the_summed_direction_and_the_largest_magnitude(rigged):
    _, rig, _ = rigged
    names = ["frontalis_inner_l", "frontalis_major_l"]
    both = rig.muscle_displacement({names[0]: 1.0, names[1]: 0.7})
    single = [rig.muscle_displacement({names[0]: 1.0}), rig.muscle_displacement({names[1]: 0.7})]
    total = single[0] + single[1]
    big = np.maximum(*[np.linalg.norm(s, axis=1) for s in single])
    moving = np.linalg.norm(total, axis=1) > 1e-9
    assert moving.sum() > 100
    np.testing.assert_allclose(np.linalg.norm(both, axis=1)[moving], big[moving], rtol=1e-9)
    cos = (both[moving] * total[moving]).sum(axis=1) / (np.linalg.norm(both[moving], axis=1)
                                                       * np.linalg.norm(total[moving], axis=1))
    np.testing.assert_allclose(cos, 1.0, atol=1e-9)
    # Outside the groups the displacements add up.
    ungrouped = ["nasalis_dilator_l", "orbicularis_oris_upper_l"]
    np.testing.assert_allclose(rig.muscle_displacement({ungrouped[0]: 1.0, ungrouped[1]: 0.5}),
                               rig.muscle_displacement({ungrouped[0]: 1.0})
                               + rig.muscle_displacement({ungrouped[1]: 0.5}), atol=1e-15)


# --- the parametric layer ---------------------------------------------------------------

def test_lip_split_keeps_the_lips_apart(rigged):
    head, rig, _ = rigged
    label = split_lips(head)
    for fp, expect in (("8.1", 1), ("2.2", 1), ("2.6", 1), ("8.5", 1), ("8.2", -1), ("2.3", -1), ("2.8", -1),
                       ("8.7", -1), ("2.10", -1), ("2.1", -1), ("8.3", 0), ("2.4", 0), ("9.15", 1), ("4.1", 1)):
        assert (label[list(head.feature_points[fp].vertices)] == expect).all(), fp
    m = _fp_motion(head, {3: 512.0})
    assert np.linalg.norm(m["8.2"]) > 10 * np.linalg.norm(m["8.1"])
    # Lower-face muscles leave the upper lip where it is.
    d = rig.deform({"depressor_labii_inferioris_l": 5.0, "mentalis_l": 5.0})["skin"] - head.skin.vertices
    upper = label > 0
    assert np.abs(d[upper]).max() == 0 and np.abs(d[label < 0]).max() > 1e-3


def test_jaw_sector_fades_towards_the_neck(rigged):
    head, rig, _ = rigged
    w = rig.jaw_weights
    assert w[list(head.feature_points["2.1"].vertices)].min() == 1.0
    assert w[list(head.feature_points["2.10"].vertices)].min() == 1.0
    assert w[list(head.feature_points["4.1"].vertices)].max() == 0.0
    skin = head.skin.vertices
    throat = (np.abs(skin[:, 0]) < 0.005) & (skin[:, 1] < head.fp_position("2.1")[1]) & (skin[:, 2] > 0.03)
    partly = (w[throat] > 0) & (w[throat] < 1)
    assert partly.sum() >= 3  # the cosine fade under the chin
    assert (w[skin[:, 1] < -0.16] == 0).all()  # the neck's base stays
    lo, up = rig.neck_lines
    y = np.array([[0, up + 0.01, 0], [0, 0.5 * (lo + up), 0], [0, lo - 0.01, 0]])
    np.testing.assert_allclose(rig.neck_weight(y), [1.0, 0.5, 0.0])


def test_eyeball_centre_from_the_two_farthest_vertices():
    rng = np.random.default_rng(1)
    d = rng.normal(size=(400, 3))
    sphere = d / np.linalg.norm(d, axis=1)[:, None] * 0.012 + [0.03, 0.04, 0.08]
    centre, radius = eyeball_centre(sphere)
    np.testing.assert_allclose(centre, [0.03, 0.04, 0.08], atol=2e-4)
    assert radius == pytest.approx(0.012, rel=1e-3)
    head = load_generic_head()
    c, _ = eyeball_centre(head.parts["eye_l"].vertices)
    assert np.linalg.norm(c - head.parts["eye_l"].centre) < 1e-3  # the build script's sphere fit agrees


# --- conformance --------------------------------------------------------------------------

@pytest.mark.parametrize("n", [n for n in range(3, 69) if FAPS[n].kind == "translation"])
def test_translation_faps_move_their_point_and_not_unrelated_ones(rigged, n):
    head, _, report = rigged
    fap = FAPS[n]
    fp = fap.feature_points[0]
    ids = [i for i in FP_IDS if i in head.feature_points]
    bad = dict(zip(ids, unrelated(fp, ids)))
    for value in ((512.0,) if fap.direction == "U" else (512.0, -512.0)):
        goal = value * fap_unit(n, head.fapu) * fap.axis_vector
        motion = _fp_motion(head, {n: value})
        g = np.linalg.norm(goal)
        if n in (3, 14, 15):  # the jaw turns: the chin's motion along the FAP's axis is what counts
            assert abs(motion[fp] @ goal / g - g) <= 0.10 * g, (fap.name, value)
        else:
            assert np.linalg.norm(motion[fp] - goal) <= 0.10 * g, (fap.name, value, report[n].route)
        leaks = {i: np.linalg.norm(m) / g for i, m in motion.items() if bad[i]}
        worst = max(leaks, key=leaks.get)
        assert leaks[worst] <= 0.20, (fap.name, value, worst, leaks[worst])
    half = _fp_motion(head, {n: 256.0 if fap.direction == "U" else -256.0})[fp]
    full = _fp_motion(head, {n: 512.0 if fap.direction == "U" else -512.0})[fp]
    np.testing.assert_allclose(half, full / 2, atol=1e-9)


def test_most_faps_come_from_the_model(rigged):
    _, _, report = rigged
    routes = {n: r.route for n, r in report.items()}
    assert routes[3] == routes[14] == routes[15] == "jaw"
    assert all(routes[n] == "eyelid" for n in (19, 20, 21, 22))
    assert all(routes[n] == "neck" for n in (48, 49, 50))
    muscles = [n for n, r in routes.items() if r == "muscles"]
    assert len(muscles) >= 30, routes
    for n in (4, 5, 12, 31, 33, 41, 53, 59, 61):  # lips, brows, cheeks, corners, nose wings
        assert routes[n] == "muscles", (n, routes[n])
    assert sum("falloff" in r for r in routes.values()) <= 18


@pytest.mark.parametrize("n, fp, sense", [(23, "3.5", [1, 0, 0]), (25, "3.5", [0, -1, 0]), (24, "3.6", [1, 0, 0]),
                                          (49, "9.3", [1, 0, 0]), (48, "9.3", [0, -1, 0]), (50, "11.4", [-1, 0, 0])])
def test_rotations_turn_the_right_way(rigged, n, fp, sense):
    head, _, _ = rigged
    m = _fp_motion(head, {n: 20000.0})[fp]
    assert m @ np.asarray(sense, float) > 0.5 * np.linalg.norm(m) > 0


def test_head_turn_fades_over_the_neck_and_matches_the_model(rigged):
    head, rig, _ = rigged
    neutral = {n: p.vertices for n, p in head.parts.items()}
    base = head.skin.vertices[:, 1] < rig.neck_lines[0]
    # On a border the table is the model; between two borders the chords stay within 0.5 mm.
    for value, within in ((20000.0, 1e-9), (-15000.0, 5e-4)):
        table = apply_fat(head.fat, neutral, {49: value}, head.fapu)
        model = rig.deform_faps({49: value})
        assert max(np.abs(table[k] - model[k]).max() for k in table) < within, value
        skin = table["skin"] - neutral["skin"]
        assert np.abs(skin[base]).max() < within and np.linalg.norm(skin, axis=1).max() > 5e-3


def test_tables_reproduce_the_model_at_the_authoring_value(rigged):
    """The tables as the model makes them (not separated) are the model at the authoring
    value; the head's tables are those separated (fmc.separate), unfolded (fmc.unfold) and
    bounded (fmc.bound)."""
    head, rig, _ = rigged
    raw, _ = author_from_muscles(head, rig=rig, separate=False, unfold=False, bound=False)
    separated = bound_tables(head, unfold_tables(head, separate_tables(head, raw, keep=JAW_FAPS))[0], keep=JAW_FAPS)
    neutral = {n: p.vertices for n, p in head.parts.items()}
    for n in (19, 31, 61, 12):
        assert np.array_equal(apply_fat(separated, neutral, {n: 400.0}, head.fapu)["skin"],
                              apply_fat(head.fat, neutral, {n: 400.0}, head.fapu)["skin"]), n
    for values in ({3: 512.0}, {19: 512.0}, {31: 512.0}, {61: 512.0}, {23: 9000.0}):
        table = apply_fat(raw, neutral, values, head.fapu)
        model = rig.deform_faps(values)
        assert max(np.abs(table[k] - model[k]).max() for k in table) < 1e-6, values
    # A lip FAP's table keeps its share of the model's whole-lip motion: its contour's
    # (innerness) and its place's across the mouth (the partition, the corners here).
    w = innerness(head)
    side = lip_side(head, "skin")

    def corner_l(contour):
        upper, lower, _ = LIP_NODES[contour]
        x = head.skin.vertices[:, 0]
        cuts = [smooth_partition(np.array([[x[list(head.feature_points[i].vertices)].min(),
                                             x[list(head.feature_points[i].vertices)].max()] for i in ids]), x)[:, -1]
                for ids in (upper, lower)]
        return np.where(side < 0, cuts[1], cuts[0])

    for n, share in ((12, w * corner_l("inner")), (59, (1.0 - w) * corner_l("outer"))):
        table = apply_fat(raw, neutral, {n: -512.0}, head.fapu)
        model = rig.deform_faps({n: -512.0})
        expected = neutral["skin"] + share[:, None] * (model["skin"] - neutral["skin"])
        assert np.abs(table["skin"] - expected).max() < 1e-6, n


def test_lids_close_the_eye(rigged):
    head, _, _ = rigged
    m = _fp_motion(head, {19: 512.0, 21: 512.0})
    gap = (head.fp_position("3.1") + m["3.1"]) - (head.fp_position("3.3") + m["3.3"])
    assert abs(gap[1]) < 0.05 * head.fapu.IRISD0  # the margins meet


def test_pupils_dilate_by_the_fapu(rigged):
    head, _, report = rigged
    neutral = {n: p.vertices for n, p in head.parts.items()}
    for n, part in ((29, "eye_l"), (30, "eye_r")):
        assert report[n].route == "pupil"
        moved = apply_fat(head.fat, neutral, {n: 512.0}, head.fapu)
        rim = np.linalg.norm(moved[part] - neutral[part], axis=1).max()
        assert 0.8 * 0.5 * 512 * head.fapu.IRISD0 / 1024 < rim <= 0.5 * 512 * head.fapu.IRISD0 / 1024 * (1 + 1e-9)


# --- visemes and expressions ----------------------------------------------------------------

def _pose(head, key):
    neutral = {n: p.vertices for n, p in head.parts.items()}
    moved = apply_fat(head.fat, neutral, {key: 63.0}, head.fapu)
    return {i: head.fp_position(i, moved) for i in head.feature_points}


def test_high_level_data_uses_low_level_faps():
    assert len(HIGH_LEVEL_FAPS) == 22
    for values in HIGH_LEVEL_FAPS.values():
        assert all(3 <= n <= 68 for n in values)


def test_visemes_open_close_and_round_the_mouth(rigged):
    head, _, _ = rigged
    base = _pose(head, (1, 0))
    width0 = base["8.3"][0] - base["8.4"][0]

    def gap(p):
        return np.linalg.norm(p["2.2"] - p["2.3"])

    assert gap(_pose(head, (1, 1))) < 1e-3  # p b m: lips together within 1 mm
    for v, least in ((10, 0.015), (13, 0.015), (11, 0.008)):  # open vowels
        assert gap(_pose(head, (1, v))) > least, v
    for v in (6, 9, 14):  # rounded: the mouth narrows by over 10 %
        p = _pose(head, (1, v))
        assert p["8.3"][0] - p["8.4"][0] < 0.9 * width0, v
    for v in (7, 12):  # spread: wider
        p = _pose(head, (1, v))
        assert p["8.3"][0] - p["8.4"][0] > 1.08 * width0, v
    lower_teeth = _pose(head, (1, 10))["9.11"] - base["9.11"]
    assert lower_teeth[1] < -0.01  # the lower teeth drop with the jaw


def test_expressions_do_what_the_reference_describes(rigged):
    head, _, _ = rigged
    base = _pose(head, (2, 0))
    d = {e: {i: p - base[i] for i, p in _pose(head, (2, e)).items()} for e in range(1, 7)}
    assert d[1]["8.3"][1] > 0.003 and d[1]["8.4"][1] > 0.003  # joy: corners up
    assert d[2]["4.1"][1] > 0.002 and d[2]["8.3"][1] < -0.001  # sadness: inner brows up, corners down
    assert d[3]["4.1"][1] < -0.002 and d[3]["4.1"][0] < 0 < d[3]["4.2"][0]  # anger: brows down and together
    assert d[4]["4.1"][1] > 0.003 and d[4]["3.1"][1] > 0.001  # fear: brows up, eyes wider
    assert d[5]["8.5"][1] > 0.005 and d[5]["9.1"][1] > 0.003  # disgust: upper lip and nose wings up
    assert d[6]["4.3"][1] > 0.005 and d[6]["2.1"][1] < -0.005  # surprise: brows up, jaw dropped


def test_authored_head_round_trips_through_a_valid_glb(rigged, tmp_path, validate_gltf):
    from mpeg4.io import read_glb, write_glb

    head, _, _ = rigged
    path = write_glb(head, tmp_path / "muscles.glb")
    assert validate_gltf(path)["issues"]["numErrors"] == 0
    back = read_glb(path)
    neutral = {n: p.vertices for n, p in head.parts.items()}
    for values in ({3: 700.0, 49: -8000.0}, {19: 300.0, 31: -200.0, (2, 1): 40.0, 61: 150.0}):
        a = apply_fat(head.fat, neutral, values, head.fapu)
        b = apply_fat(back.fat, {n: p.vertices for n, p in back.parts.items()}, values, back.fapu)
        assert max(np.abs(a[k] - b[k]).max() for k in a) < 1e-6


# --- bad input ---------------------------------------------------------------------------------

@pytest.mark.parametrize("missing, needle", [
    ("3.13", r"left eyelids need feature point 3.13"),
    ("3.4", r"right eyelids need feature point 3.4"),
    ("10.9", r"jaw pivot.* needs feature point 10.9"),
    ("2.3", r"lip split needs feature point 2.3"),
    ("8.7", r"muscle depressor_labii_inferioris_l.* needs feature point 8.7"),
])
def test_missing_points_are_named(missing, needle):
    head = _bare_head()
    del head.feature_points[missing]
    with pytest.raises(InputError, match=needle):
        MuscleRig.from_head(head)


def _placement_with(name, **change):
    data = load_placement()
    data["muscles"][name].update(change)
    return data


@pytest.mark.parametrize("name, change, needle", [
    ("risorius_l", dict(head={"at": {"8.3": 1.0}, "off": [0, 0, 0]}, tail={"at": {"8.3": 1.0}, "off": [0, 0, 0]}),
     r"risorius_l.*head and tail coincide"),
    ("mentalis_l", dict(zone=0), r"mentalis_l.*zone half-angle 0"),
    ("frontalis_inner_l", dict(fall_start=1.5, fall_end=1.2), r"frontalis_inner_l.*0 < start < end"),
    ("orbicularis_oris_upper_l", dict(semi_axes=[0.5, 0.0]), r"orbicularis_oris_upper_l.*semi-axes"),
    ("zygomaticus_major_l", dict(elasticity=-0.1), r"zygomaticus_major_l.*elasticity"),
    ("risorius_l", dict(head={"at": {"8.3": 1.0}, "off": [0, 0, 9.0]}, tail={"at": {"8.3": 1.0}, "off": [0, 0, 8.0]}),
     r"risorius_l moves no skin vertex"),
    ("risorius_l", dict(tail={"at": {"8.3": 0.5}, "off": [0, 0, 0]}), r"risorius_l.*weights sum to 0.5"),
    ("risorius_l", dict(group="cheeks"), r"unknown combination group 'cheeks'"),
])
def test_degenerate_placement_is_refused(name, change, needle):
    with pytest.raises(InputError, match=needle):
        MuscleRig.from_head(_bare_head(), _placement_with(name, **change))


def test_degenerate_jaw_and_lids_are_refused():
    head = _bare_head()
    data = load_placement()
    data["jaw"]["neck"] = dict(data["jaw"]["chin"])
    with pytest.raises(InputError, match="jaw sector is empty"):
        MuscleRig.from_head(head, data)
    head.feature_points["3.13"], head.feature_points["3.1"] = head.feature_points["3.1"], head.feature_points["3.13"]
    with pytest.raises(InputError, match="upper lid's points are out of order"):
        MuscleRig.from_head(head)
    with pytest.raises(InputError, match="has no volume"):
        eyeball_centre(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0.5, 0.5, 0]], float))


def test_cli_authors_with_either_method(tmp_path):
    from typer.testing import CliRunner

    from fmc.cli import app
    from mpeg4.generic_head import generic_head_path
    from mpeg4.io import read_glb

    out = CliRunner().invoke(app, ["author", str(generic_head_path()), "--method", "muscles", "-o",
                                   str(tmp_path / "m.glb")])
    assert out.exit_code == 0, out.output
    assert "muscles" in out.output and "jaw 3" in out.output
    assert len(read_glb(tmp_path / "m.glb").fat) == 66 + 15 + 7
    bad = CliRunner().invoke(app, ["author", str(generic_head_path()), "--method", "springs", "-o",
                                   str(tmp_path / "x.glb")])
    assert isinstance(bad.exception, InputError) and "--method shapes or --method muscles" in str(bad.exception)
    assert not (tmp_path / "x.glb").exists()


def test_a_head_split_along_seams_gets_the_same_weights(rigged):
    # A textured head stores the vertices of its seams twice; the flood fill and the jaw's
    # fade must run across the copies as across the originals.
    from mpeg4.seams import split_vertices

    head, rig, _ = rigged
    skin = head.skin
    tri = skin.triangles.copy()
    right = skin.vertices[tri].mean(axis=1)[:, 0] < 0
    seam = np.intersect1d(np.unique(tri[right]), np.unique(tri[~right]))
    copy_of = {v: skin.n_vertices + k for k, v in enumerate(seam)}
    tri[right] = np.vectorize(lambda v: copy_of.get(v, v))(tri[right])
    split = split_vertices(head, "skin", np.r_[np.arange(skin.n_vertices), seam], tri)
    other = MuscleRig.from_head(split)
    assert np.isfinite(other.jaw_weights).all()
    n = skin.n_vertices
    np.testing.assert_allclose(other.jaw_weights[:n], rig.jaw_weights, atol=1e-9)
    np.testing.assert_allclose(other.jaw_weights[n:], rig.jaw_weights[seam], atol=1e-9)


def test_no_fap_moves_a_part_it_does_not_own(rigged):
    from fmc.conformance import part_leaks

    head, _, _ = rigged
    leaks = part_leaks(head, 300.0)
    moved = {n: {p: round(m * 1e3, 3) for p, m in d.items()} for n, d in leaks.items() if d}
    assert len(leaks) >= 60 and not moved, moved
