"""Sealed mouths: a mesh that joins its lips is ripped open along its lip line (fmc.clone.seal)."""

from pathlib import Path

import numpy as np
import pytest
from scipy.sparse.csgraph import dijkstra

from fmc.clone.seal import PARTING, rip_mouth, sealed_mouth
from mpeg4.head import FeaturePointBinding, Head, Part
from mpeg4.surface import edge_graph

ROOT = Path(__file__).resolve().parents[2]
MASK = ROOT.parent / "shared" / "data" / "foreign_heads" / "mediapipe_canonical_face" / "canonical_face_model.obj"


def _sealed_face(step: float = 0.005):
    """A flat grid (metres, y up) whose mouth line y = 0 runs from 2.4 at x = -0.02 to
    2.5 at x = +0.02; the inner lips' midpoints 2.2 and 2.3 on one vertex, as a detector
    puts them on a mesh that joins the lips."""
    xs = np.arange(-0.04, 0.04 + 1e-9, step)
    ys = np.arange(-0.03, 0.03 + 1e-9, step)
    gx, gy = np.meshgrid(xs, ys)
    v = np.c_[gx.ravel(), gy.ravel(), np.zeros(gx.size)]
    nx = len(xs)
    tris = []
    for r in range(len(ys) - 1):
        for c in range(nx - 1):
            a, b, d, e = r * nx + c, r * nx + c + 1, (r + 1) * nx + c, (r + 1) * nx + c + 1
            tris += [[a, b, e], [a, e, d]]
    at = lambda x, y: int(np.argmin(np.linalg.norm(v[:, :2] - [x, y], axis=1)))
    fps = {"2.4": at(-0.02, 0), "2.5": at(0.02, 0), "2.2": at(0, 0), "2.3": at(0, 0),
           "2.6": at(0.01, 0), "2.7": at(-0.01, 0), "2.8": at(0.01, 0), "2.9": at(-0.01, 0)}
    return Head({"skin": Part("skin", v, np.array(tris))},
                {k: FeaturePointBinding.at_vertex("skin", i) for k, i in fps.items()})


def test_a_sealed_mouth_is_ripped_along_its_line():
    head = _sealed_face()
    line = sealed_mouth(head)
    assert line is not None and len(line) == 9  # x = -0.02 .. 0.02 every 5 mm
    out, ripped = rip_mouth(head)
    assert ripped == 7  # the corners stay joined
    n = head.skin.n_vertices
    v, t = out.skin.vertices, out.skin.triangles
    assert out.skin.n_vertices == n + 7
    assert np.allclose(v[n:], head.skin.vertices[line[1:-1]] - [0, PARTING, 0])
    # Triangles below the line use the copies, those above the originals.
    centre = v[t].mean(axis=1)
    uses_copy = (t >= n).any(axis=1)
    assert (centre[uses_copy, 1] < 0).all()
    touching_line = np.isin(t, line[1:-1]).any(axis=1)
    assert (centre[touching_line, 1] > 0).all()
    # The lips now meet only at the corners: along the mesh from 2.2 to 2.3 is the way
    # round a corner, not across.
    a, b = out.feature_points["2.2"].vertices[0], out.feature_points["2.3"].vertices[0]
    assert b == n + list(line[1:-1]).index(a)
    along = dijkstra(edge_graph(v, t), indices=a)[b]
    assert along > 0.035
    assert sealed_mouth(out) is None
    # Each lower inner point on the copy of its upper partner's vertex.
    for upper, lower in (("2.6", "2.8"), ("2.7", "2.9")):
        assert np.allclose(out.fp_position(lower), out.fp_position(upper) - [0, PARTING, 0])


def test_an_open_mouth_is_left_as_it_is():
    from mpeg4.generic_head import load_generic_head

    head = load_generic_head()
    assert sealed_mouth(head) is None
    same, ripped = rip_mouth(head)
    assert ripped == 0 and same is head


@pytest.mark.skipif(not MASK.exists(), reason=f"the MediaPipe face mask is not there ({MASK})")
def test_the_masks_jaw_opens_its_mouth_without_a_sheet():
    # The mask joins its lips over a 5 mm gap. Cloned before the rip, the jaw dragged 16
    # triangles into a sheet across the open mouth: each with corners apart by more than
    # half the chin's travel (up to 0.90 of it). Now none: the largest is 0.43.
    pytest.importorskip("mediapipe")
    from chain import clone_onto
    from mpeg4.fat import apply_fat

    head, warnings = clone_onto(None, MASK)
    assert any("joins the lips" in w for w in warnings)
    skin = head.skin.vertices
    moved = apply_fat(head.fat, {"skin": skin}, {3: 512}, head.fapu)["skin"] - skin
    d = np.linalg.norm(moved, axis=1)
    corners = d[head.skin.triangles]
    assert (corners.max(axis=1) - corners.min(axis=1)).max() < 0.5 * d.max()
    # The inner lips part: 2.3 goes down with the jaw, 2.2 stays.
    gap = lambda p: np.linalg.norm(head.fp_position("2.2", {"skin": p}) - head.fp_position("2.3", {"skin": p}))
    assert gap(skin + moved) > gap(skin) + 0.008
