"""recon.shape.template_fit: the generic head fitted to a re-meshed ICT identity's surface.

The found points are the identity's true eye, nose and mouth points with 1.5 mm of noise
added; the fit must place the points no render shows (eyebrows, hairline, ears) near the
truth and pull the noisy points towards it.
"""

import numpy as np
import pytest

from mpeg4.errors import InputError
from mpeg4.io import load_head
from recon.shape.template_fit import fit_generic

SEEN_GROUPS = (3, 8, 9)
NOT_SKIN = ("3.5", "3.6", "9.8", "9.9", "9.10", "9.11")  # pupils, teeth


@pytest.fixture(scope="module")
def identity(remeshed):
    """The skin of a re-meshed identity (its largest OBJ group) in the neutral frame, and its true points."""
    mf = remeshed(7, "obj")
    head = load_head(mf.path, feature_points=False)
    skin = max(head.parts.values(), key=lambda p: p.n_vertices)
    back = np.linalg.inv(mf.to_file)

    def to_neutral(p):
        return np.asarray(p) @ back[:3, :3].T + back[:3, 3]

    truth = {i: to_neutral(p) for i, p in mf.points.items()}
    return to_neutral(skin.vertices), skin.triangles, truth


def _noisy(truth, ids, sigma, seed=0):
    rng = np.random.default_rng(seed)
    return {i: truth[i] + rng.normal(0, sigma / np.sqrt(3), 3) for i in ids}


def test_points_no_render_shows_follow_the_shape(identity):
    v, t, truth = identity
    seen = [i for i in truth if int(i.split(".")[0]) in SEEN_GROUPS and i not in NOT_SKIN]
    seen += ["2.1", "2.2", "2.3", "2.4", "2.5"]
    found = _noisy(truth, seen, 0.0015)
    fit = fit_generic(v, t, found, give=1e-3)
    assert fit.gap < 0.0005  # the generic skin lies on the surface

    def err(i):
        return 1000 * np.linalg.norm(fit.points[i] - truth[i])

    brows = [err(i) for i in ("4.1", "4.2", "4.3", "4.4", "4.5", "4.6")]
    hairline = [err(i) for i in ("11.1", "11.2", "11.3")]
    ears = [err(i) for i in ("10.1", "10.2", "10.5", "10.6", "10.9", "10.10")]
    assert np.median(brows) < 2.5 and max(brows) < 4.0, brows
    assert np.median(hairline) < 3.0 and np.median(ears) < 8.0, (hairline, ears)
    # The noisy points come out nearer the truth than they went in.
    before = np.median([1000 * np.linalg.norm(found[i] - truth[i]) for i in seen])
    after = np.median([err(i) for i in seen])
    assert after < 0.7 * before, (before, after)
    # Points inside the head are carried by the same map.
    assert np.isfinite(fit.move(np.zeros((1, 3)))).all()


def test_exact_anchors_are_kept_and_outliers_left_out(identity):
    v, t, truth = identity
    seen = [i for i in truth if int(i.split(".")[0]) in SEEN_GROUPS and i not in NOT_SKIN]
    found = {i: truth[i] for i in seen}
    found["9.3"] = truth["9.3"] + np.array([0.0, 0.03, 0.0])  # a detection 3 cm off
    fit = fit_generic(v, t, found, give=0.0)
    assert "9.3" not in fit.anchors and len(fit.anchors) == len(seen) - 1
    assert 1000 * np.linalg.norm(fit.points["9.3"] - truth["9.3"]) < 3.0
    close = [1000 * np.linalg.norm(fit.points[i] - truth[i]) for i in fit.anchors]
    assert np.median(close) < 0.5
    with pytest.raises(InputError, match="only 3 found feature points"):
        fit_generic(v, t, {i: truth[i] for i in ("9.3", "8.1", "3.7")})
