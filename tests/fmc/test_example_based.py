"""Example-based cloning: compositing, PCA parameters, cardinal weights, exact interpolation,
accuracy on ICT identities, animation files in and out, clear errors."""

import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from fmc.example_based import (FEATURE_POINTS, VERBAL, CardinalBasis, KeyModels, Parameterisation,
                               Retargeter, combined_name, composite, composite_key_models, cubic_bspline,
                               key_models_from_shapes, load_feature_points, read_animation, smooth_importance,
                               target_key_models, vertex_importance, write_retargeted)
from mpeg4 import InputError
from mpeg4.generic_head import load_generic_head

ROOT = Path(__file__).resolve().parents[2]
SMALL = ["jawOpen", "mouthSmile_L", "mouthSmile_R", "browInnerUp_L", "mouthPucker", "eyeBlink_R"]


@pytest.fixture(scope="module")
def generic_keys():
    """The generic head's 104 key-models (14 visemes, 6 expressions, 84 composites)."""
    head = load_generic_head()
    keys, importance = composite_key_models(key_models_from_shapes(head))
    return keys, importance


def _bench():
    spec = importlib.util.spec_from_file_location("example_based_bench", ROOT / "benchmarks" / "example_based.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _small_head():
    head = load_generic_head()
    head.morph_targets = {n: head.morph_targets[n] for n in SMALL}
    return head


def _other_face(head):
    """The head stretched into another face (wider, shorter), without morph targets."""
    s = np.array([1.08, 0.95, 1.0])
    out = head.with_vertices({n: p.vertices * s for n, p in head.parts.items()})
    for p in out.parts.values():
        if p.centre is not None:
            p.centre = p.centre * s
    out.morph_targets = {}
    return out


# --- data -------------------------------------------------------------------------------

def test_the_feature_point_subset_is_documented_data():
    points = load_feature_points()
    ids = [p["id"] for p in points]
    assert len(ids) == 20 == len(set(ids)) and tuple(ids) == FEATURE_POINTS
    assert all(len(p["moves_with"]) > 5 for p in points)
    head = load_generic_head()
    assert all(head.feature_points[i].part == "skin" for i in ids)
    # Every point is moved by some viseme or expression of the generic head.
    par = Parameterisation.fit(key_models_from_shapes(head), threshold=0.0)
    keys = key_models_from_shapes(head)
    moved = np.abs(np.einsum("mc,ncx->nmx", par.weights, keys.displacements[:, par.vertices])).max(axis=(0, 2))
    assert moved.min() > 1e-4  # metres


# --- the pieces -------------------------------------------------------------------------

def test_cubic_bspline_is_the_c2_uniform_spline():
    t = np.array([0.0, 0.5, 1.0, 1.5, 2.0, 2.5])
    assert np.allclose(cubic_bspline(t), [2 / 3, 23 / 48, 1 / 6, 1 / 48, 0, 0])
    h = 1e-4
    for knot in (1.0, 2.0):  # value, slope and curvature continuous at the knots
        left, mid, right = cubic_bspline(np.array([knot - h, knot, knot + h]))
        assert abs((mid - left) / h - (right - mid) / h) < 1e-3


def test_cardinal_basis_interpolates_and_reproduces_affine_functions():
    rng = np.random.default_rng(3)
    params = rng.normal(size=(40, 6))
    basis = CardinalBasis(params)
    assert np.abs(basis(params) - np.eye(40)).max() < 1e-9
    assert np.allclose(basis.dilation, [np.sort(np.linalg.norm(params - p, axis=1))[1] for p in params])
    p = rng.normal(size=(25, 6))
    w = basis(p)
    assert np.abs(w.sum(axis=1) - 1).max() < 1e-9  # partition of unity
    assert np.abs(w @ params - p).max() < 1e-9  # the linear part reproduces p itself


def test_composite_keeps_one_displacement_and_the_perpendicular_part_of_the_other():
    v = np.array([[0.0, -1.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    e = np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 2.0, 0.0], [1.0, 1.0, 0.0]])
    c = composite(v, e, np.array([1.0, 0.0, 1.0, 0.5]))
    assert np.allclose(c[0], [1.0, -1.0, 0.0])  # verbal whole, emotional's x only
    assert np.allclose(c[1], [1.5, 0.5, 0.0])  # emotional whole, verbal's part across it
    assert np.allclose(c[2], [0.0, 2.0, 0.0])  # the verbal leaves it still: the emotional's
    assert np.allclose(c[3], (c[0] + c[1]) / 2)  # mid-band: half of each candidate
    hard = composite(v, e, np.array([1.0, 0.0, 1.0, 0.5]), band=(0.5, 0.5))
    assert np.allclose(hard[3], c[0])  # the paper's switch: 0.5 is verbal
    w = composite(v[:1], e[:1], np.array([0.6]))[0]  # t = 0.7: smooth step 0.784
    assert np.allclose(w, 0.784 * c[0] + 0.216 * c[1])
    # softness s: of the other's component along k, |k|^2 / (|k|^2 + s^2) is removed
    soft = composite(np.array([[0.0, -1.0, 0.0]]), np.array([[0.0, 3.0, 0.0]]), np.array([1.0]), softness=1.0)
    assert np.allclose(soft[0], [0.0, -1.0 + 3.0 * 0.5, 0.0])
    with pytest.raises(InputError, match="band"):
        composite(v, e, np.ones(4), band=(0.8, 0.2))
    with pytest.raises(InputError, match="softness"):
        composite(v, e, np.ones(4), softness=-1.0)


def test_importance_is_smoothed_along_the_mesh_edges():
    # a strip of 40 columns of 2 vertices (78 triangles), importance 1 on the left half
    n = 40
    tri = np.concatenate([[[2 * k, 2 * k + 1, 2 * k + 2], [2 * k + 1, 2 * k + 3, 2 * k + 2]] for k in range(n - 1)])
    step = np.repeat((np.arange(n) < n // 2).astype(float), 2)
    imp = np.r_[step, 0.7]  # and a vertex on no triangle
    out = smooth_importance(imp, tri, steps=20)
    col = out[:-1].reshape(n, 2).mean(axis=1)
    assert out[-1] == 0.7 and np.array_equal(smooth_importance(imp, tri, steps=0), imp)
    assert (np.diff(col) <= 1e-12).all() and 0 <= out.min() and out.max() <= 1  # monotone, in [0, 1]
    assert col[0] > 0.99 and col[-1] < 0.01  # far from the step: unchanged
    assert np.abs(np.diff(col)).max() < 0.2  # the jump of 1 is spread over the band
    assert abs(col[n // 2 - 1] + col[n // 2] - 1) < 1e-9  # symmetric about the step
    with pytest.raises(InputError, match="steps"):
        smooth_importance(imp, tri, steps=-1)


def _worst_edge_excess(keys):
    """Largest skin-edge length of a composite over the longest the edge has in the neutral,
    the verbal, the emotional key-model or their sum, over the 84 composites."""
    sl = keys.part_slices()["skin"]
    tri = keys.head.skin.triangles
    e = np.unique(np.sort(np.r_[tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]], axis=1), axis=0)

    def lengths(d):
        x = keys.neutral[sl] + d[sl]
        return np.linalg.norm(x[e[:, 0]] - x[e[:, 1]], axis=1)

    l0, worst = lengths(np.zeros_like(keys.neutral)), 0.0
    for i, name in enumerate(keys.names[20:], start=20):
        em, vb = name.split("+")
        dv, de = keys.displacements[keys.index(vb)], keys.displacements[keys.index(em)]
        ref = np.maximum.reduce([l0, lengths(dv), lengths(de), lengths(dv + de)])
        worst = max(worst, float((lengths(keys.displacements[i]) / ref).max()))
    return worst


def test_composites_do_not_tear_the_skin(generic_keys):
    keys = generic_keys[0]
    # the paper's rule (hard switch at 0.5, full projection) stretches a skin edge to 9.7
    # times its longest in any of the parts (expression_disgust+viseme_A): the lips stay
    # while the skin next to them moves; blended over a smoothed band with a soft projection
    # the worst is 2.5 (expression_surprise+viseme_f_v)
    assert _worst_edge_excess(keys) < 3.0
    paper = composite_key_models(key_models_from_shapes(keys.head), smoothing_steps=0, band=(0.5, 0.5),
                                 softness=0.0)[0]
    assert _worst_edge_excess(paper) > 9.0


def test_importance_propagates_within_the_radius_and_combines():
    x = np.c_[np.arange(30) * 0.001, np.zeros(30), np.zeros(30)]  # a line of vertices 1 mm apart
    verbal = np.zeros((2, 30, 3))
    verbal[0, 0, 1] = 0.004  # the lip: strong
    verbal[1, 5, 1] = 0.0004  # a weak verbal motion
    emotional = np.zeros((1, 30, 3))
    emotional[0, 20, 0] = 0.003
    emotional[0, 5, 0] = 0.003
    imp = vertex_importance(x, verbal, emotional, radius_verbal=0.0035, radius_emotional=0.0015, s1=0.5, s2=0.3)
    assert (imp[:4] == 1).all()  # within 3.5 mm of the lip
    assert imp[5] == pytest.approx(0.1 / 1.1)  # weak verbal, strong emotional: its share
    assert imp[20] == 0 and imp[19] == 0 and imp[29] == 0


def test_compositing_keeps_verbal_motion_where_speech_matters(generic_keys):
    keys, imp = generic_keys
    assert len(keys) == 14 + 6 + 84 and keys.names[:14] == list(VERBAL)
    head = keys.head
    softness = 0.05 * head.fapu.MW0
    fp = {i: head.feature_points[i].vertices[0] for i in ("8.3", "8.1", "2.2", "2.1", "4.1", "4.3", "3.1")}
    assert all(imp[fp[i]] >= 0.75 for i in ("8.3", "8.1", "2.2", "2.1"))  # mouth and chin speak
    assert all(imp[fp[i]] <= 0.25 for i in ("4.1", "4.3", "3.1"))  # brows and lids emote
    for e, v in (("expression_joy", "viseme_A"), ("expression_anger", "viseme_U")):
        c = keys.displacements[keys.index(combined_name(e, v))]
        dv, de = keys.displacements[keys.index(v)], keys.displacements[keys.index(e)]
        n = np.linalg.norm(dv, axis=1)
        moving = (imp >= 0.75) & (n > 2 * softness)  # clearly verbal, moving well above the softness
        u = dv[moving] / n[moving, None]
        along, other = (c[moving] * u).sum(axis=1), (de[moving] * u).sum(axis=1)
        # the viseme's motion kept; of the expression's along it at least 80 % removed
        assert (np.abs(along - n[moving]) <= 0.2 * np.abs(other) + 1e-12).all()
        assert moving.sum() > 100
        # clearly emotional and clearly verbal vertices keep the paper's candidates exactly
        # when the projection is not softened
        hard = composite(dv, de, imp, softness=0.0)
        for kept, region in ((dv, imp >= 0.75), (de, imp <= 0.25)):
            mv = region & (np.linalg.norm(kept, axis=1) > 1e-5)
            uk = kept[mv] / np.linalg.norm(kept[mv], axis=1, keepdims=True)
            assert np.abs((hard[mv] * uk).sum(axis=1) - np.linalg.norm(kept[mv], axis=1)).max() < 1e-12
            assert mv.sum() > 100


def test_pca_drops_the_parameter_dimension_on_real_key_models(generic_keys):
    keys, _ = generic_keys
    par = Parameterisation.fit(keys)
    assert len(par.neutral) == 60
    assert 10 <= par.dimension < 60
    ev = par.eigenvalues
    assert ev[par.dimension - 1] > 1e-5 * ev[0] >= ev[par.dimension]
    assert np.allclose(par.matrix @ par.matrix.T, np.eye(par.dimension), atol=1e-12)


# --- the method -------------------------------------------------------------------------

def test_every_key_model_is_interpolated_exactly(generic_keys):
    keys, _ = generic_keys
    rng = np.random.default_rng(0)
    # Any target mesh will do: 500 vertices of its own, its key-models its own.
    target = KeyModels(rng.normal(size=(500, 3)), keys.names, rng.normal(size=(len(keys), 500, 3)) * 0.01)
    r = Retargeter(keys, target)
    frames = np.array([keys.positions(n) for n in ["neutral"] + keys.names])
    w = r.weights(frames)
    assert np.abs(w - np.eye(len(keys) + 1)[:, 1:]).max() < 1e-9
    out = r.vertices(w)
    truth = np.array([target.positions(n) for n in ["neutral"] + target.names])
    assert np.abs(out - truth).max() / np.abs(target.displacements).max() < 1e-9


def test_a_target_with_the_same_key_models_gives_the_input_back_on_them(generic_keys):
    keys, _ = generic_keys
    r = Retargeter(keys, keys.select(reversed(keys.names)))  # the order follows the source
    frame = keys.positions("expression_surprise+viseme_U")
    assert np.abs(r(frame)[0] - frame).max() < 1e-12


@pytest.mark.slow
def test_accuracy_on_ict_identities(ict_npz):
    """Source → source under 0.1 % and source → target → source (FMC-drafted target
    key-models) under 0.3 % (Pyun's eq. 12), on a seeded speech-and-emotion animation."""
    bench = _bench()
    data = np.load(ict_npz)
    src_head = bench.identity_head(data, 1000)
    src = composite_key_models(key_models_from_shapes(src_head))[0]
    tgt = bench.fmc_keys(src, bench.identity_head(data, 2000))
    a, b = bench.tracks(np.random.default_rng(0), 500)
    w = bench.key_model_weights(a, b)
    skin = slice(0, src_head.skin.n_vertices)
    same, trip = bench.Errors(skin), bench.Errors(skin)
    r_self, there, back = Retargeter(src, src), Retargeter(src, tgt), Retargeter(tgt, src)
    for lo in range(0, len(w), 100):
        x = bench.blend(src, w[lo:lo + 100])
        same.add(r_self(x), x, src.neutral)
        trip.add(back(there(x)), x, src.neutral)
    assert same.eq12 < 0.1
    assert trip.eq12 < 0.3


# --- files ------------------------------------------------------------------------------

def test_animation_files_in_and_out(tmp_path, validate_gltf):
    from mpeg4.io.gltf import GlbAnimation, read_glb_animation, write_glb

    head = _small_head()
    keys = KeyModels.from_head(head)
    rng = np.random.default_rng(1)
    weights = rng.uniform(0, 0.7, (12, len(SMALL)))
    times = np.arange(12) / 25.0
    truth = np.array([np.concatenate(list(head.morphed(dict(zip(SMALL, w))).values())) for w in weights])
    # GLB: a morph-weight animation of the source head.
    write_glb(head, tmp_path / "in.glb", animation=GlbAnimation(times, dict(zip(SMALL, weights.T))))
    frames, t, warnings = read_animation(tmp_path / "in.glb", head)
    assert np.abs(frames - truth).max() < 1e-6 and np.allclose(t, times, atol=1e-6) and not warnings
    # NPZ: all parts, or the skin alone.
    np.savez(tmp_path / "all.npz", vertices=truth, times=times)
    np.savez(tmp_path / "skin.npz", vertices=truth[:, :head.skin.n_vertices], fps=25.0)
    for name in ("all.npz", "skin.npz"):
        frames, t, _ = read_animation(tmp_path / name, head)
        skin = slice(0, head.skin.n_vertices)
        assert np.allclose(frames[:, skin], truth[:, skin]) and np.allclose(t, times)
    # Out: the target head with its key-models, the weights animated.
    target = KeyModels.from_head(_sculpted(_other_face(head), head))
    r = Retargeter(keys, target, feature_points=["8.3", "8.4", "8.1", "2.3", "4.1", "3.2"])
    w = r.weights(truth)
    paths = write_retargeted(target, w, times, tmp_path / "out", npz=True)
    report = validate_gltf(paths["animation"])
    assert report["issues"]["numErrors"] == 0, report["issues"]["messages"][:3]
    anim = read_glb_animation(paths["animation"])
    assert np.allclose(np.array([anim.weights[n] for n in target.names]).T, w, atol=1e-6)
    with np.load(paths["frames"]) as f:
        assert np.abs(f["vertices"] - r(truth)).max() < 1e-6 and list(f["names"]) == target.names


def _sculpted(face, head):
    """``face`` with ``head``'s morph targets stretched like the face (a sculpted target)."""
    out = face.copy()
    s = np.array([1.08, 0.95, 1.0])
    out.morph_targets = {n: {p: type(d)(d.indices, d.vectors * s) for p, d in t.items()}
                         for n, t in head.morph_targets.items()}
    return out


def test_a_fap_stream_plays_through_the_source_tables(authored_head, tmp_path):
    from fmc.play import Player
    from mpeg4.io import write_fap
    from mpeg4.io.fap import FapStream

    values = np.full((6, 68), np.nan)
    values[:, 2] = np.linspace(0, 400, 6)  # open_jaw
    values[:, 52] = np.linspace(0, 200, 6)  # a cheek FAP
    write_fap(FapStream.from_values(values, fps=10.0), tmp_path / "s.fap")
    frames, t, _ = read_animation(tmp_path / "s.fap", authored_head)
    player = Player(authored_head)
    assert np.allclose(frames[3], player.vertices({3: 240.0, 53: 120.0})) and np.allclose(t, np.arange(6) / 10)


def test_target_key_models_are_drafted_by_fmc_where_missing():
    head = _small_head()
    keys = KeyModels.from_head(head)
    face = _other_face(head)
    face.morph_targets = {"jawOpen": _sculpted(face, head).morph_targets["jawOpen"]}
    tkeys, notes = target_key_models(keys, face)
    assert tkeys.names == keys.names and any("drafted 5 of 6" in n for n in notes)
    supplied = face.morph_targets["jawOpen"]["skin"]
    assert np.allclose(tkeys.displacements[0, supplied.indices], supplied.vectors)  # kept as given


# --- bad input --------------------------------------------------------------------------

def test_bad_input_gives_clear_errors(generic_keys):
    keys, _ = generic_keys
    with pytest.raises(InputError, match="no 'neutral'"):
        KeyModels.from_positions({"smile": np.zeros((4, 3)), "frown": np.ones((4, 3))})
    with pytest.raises(InputError, match="key-model 'frown' has 3 vertices, the neutral 4"):
        KeyModels.from_positions({"neutral": np.zeros((4, 3)), "frown": np.ones((3, 3))})
    twice = KeyModels(keys.neutral, keys.names[:5] + ["copy"], keys.displacements[[0, 1, 2, 3, 4, 2]], keys.head)
    with pytest.raises(InputError, match=f"'{keys.names[2]}' and 'copy' have the same parameters"):
        Retargeter(twice, twice)
    still = KeyModels(keys.neutral, ["jaw", "still"], np.stack([keys.displacements[0], 0 * keys.displacements[0]]),
                      keys.head)
    with pytest.raises(InputError, match="'neutral' and 'still' have the same parameters"):
        Retargeter(still, still)
    with pytest.raises(InputError, match="the target lacks the key-models viseme_p_b_m"):
        Retargeter(keys, keys.select(keys.names[1:]))
    r = Retargeter(keys.select(keys.names[:20]), keys.select(keys.names[:20]))
    with pytest.raises(InputError, match="input frames have shape"):
        r.weights(np.zeros((2, 100, 3)))
    bare = keys.head.copy()
    del bare.feature_points["8.5"]
    with pytest.raises(InputError, match="has no feature point 8.5"):
        Parameterisation.fit(KeyModels(keys.neutral, keys.names[:3], keys.displacements[:3], bare))
    with pytest.raises(InputError, match="the head lacks the shapes"):
        key_models_from_shapes(_small_head())


# --- command line -----------------------------------------------------------------------

def test_fmc_retarget(tmp_path, validate_gltf):
    from fmc.cli import app
    from mpeg4.io import save_head

    head = _small_head()
    save_head(head, tmp_path / "source.glb")
    save_head(_other_face(head), tmp_path / "target.glb")
    rng = np.random.default_rng(2)
    frames = np.array([np.concatenate(list(head.morphed(dict(zip(SMALL, w))).values()))
                       for w in rng.uniform(0, 0.8, (8, len(SMALL)))])
    np.savez(tmp_path / "anim.npz", vertices=frames, fps=25.0)
    args = [str(tmp_path / f) for f in ("source.glb", "target.glb", "anim.npz")]
    out = CliRunner().invoke(app, ["retarget", *args, "-o", str(tmp_path / "out"), "--key-models", "morph-targets",
                                   "--drafts", str(tmp_path / "drafts.glb"), "--npz"])
    assert out.exit_code == 0, out.output
    assert "drafted 6 of 6" in out.output
    for glb in (tmp_path / "out" / "animation.glb", tmp_path / "drafts.glb"):
        assert validate_gltf(glb)["issues"]["numErrors"] == 0
    # The drafts, edited or not, are the target next time: nothing is drafted.
    again = CliRunner().invoke(app, ["retarget", args[0], str(tmp_path / "drafts.glb"), args[2], "-o",
                                     str(tmp_path / "out2"), "--key-models", "morph-targets"])
    assert again.exit_code == 0 and "drafted" not in again.output
    with np.load(tmp_path / "out" / "frames.npz") as f:
        assert f["vertices"].shape == frames.shape and f["weights"].shape == (len(frames), len(SMALL))
    bad = subprocess.run([sys.executable, "-m", "fmc", "retarget", args[0], args[1], str(tmp_path / "none.npz")],
                         capture_output=True, text=True, cwd=ROOT)
    assert bad.returncode == 2 and "none.npz: animation file not found" in bad.stderr
    assert len(bad.stderr.strip().splitlines()) == 1
