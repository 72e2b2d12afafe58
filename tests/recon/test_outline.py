"""The profile between the feature points follows the side photo's outline (recon.shape.outline)."""

import numpy as np
import pytest

from mpeg4.catalogue import FEATURE_POINTS
from mpeg4.generic_head import load_generic_head
from recon.evaluate.real_photos import rendered_mask
from recon.evaluate.synthetic import view_camera
from recon.shape.deform import deform_head
from recon.shape.outline import follow_profile, match_profile, profile_controls

SCALE = 3000.0  # pixels per metre: 0.33 mm a pixel


@pytest.fixture(scope="module")
def generic():
    return load_generic_head()


def _chin_bump(head, amplitude_m):
    """The skin pushed forward between the lower lip (8.2) and the chin boss (2.10), over
    the mentolabial sulcus: a smooth bump on the midline that no feature point holds."""
    v = head.skin.vertices
    y0 = 0.5 * (head.fp_position("8.2")[1] + head.fp_position("2.10")[1])
    outer = np.clip((v[:, 2] - 0.095) / 0.01, 0.0, 1.0)  # the chin's surface, not the mouth inside it
    w = np.exp(-0.5 * (((v[:, 1] - y0) / 0.0035) ** 2 + (v[:, 0] / 0.012) ** 2)) * outer
    return head.with_vertices({"skin": v + amplitude_m * w[:, None] * [0.0, 0.0, 1.0]}), w


def _side_view(person):
    cam = view_camera("side", person.fp_position("9.3") * [0, 1, 0.3], 800, 1000, scale_px=SCALE)
    mask, _ = rendered_mask(person, cam)
    pts = {i: cam.project(person.fp_position(i)[None])[0] for i in person.feature_points
           if FEATURE_POINTS[i].side != "R"}
    return mask, cam, pts


def test_a_head_that_matches_its_outline_is_left_alone(generic):
    mask, cam, pts = _side_view(generic)
    pc = profile_controls(generic, mask, cam, pts)
    assert len(pc.vertices) > 10
    assert np.abs(pc.shift_mm).max() < 0.35  # about a pixel
    out = follow_profile(generic, pc)
    assert np.abs(out.skin.vertices - generic.skin.vertices).max() < 0.5e-3


def test_the_chin_follows_the_outline_between_the_points(generic):
    person, w = _chin_bump(generic, 0.003)
    targets = person.fp_positions()
    assert max(np.linalg.norm(targets[i] - generic.fp_position(i)) for i in targets) < 0.3e-3  # no point holds it
    head = deform_head(generic, targets)
    mask, cam, pts = _side_view(person)
    pc = profile_controls(head, mask, cam, pts)
    out = follow_profile(head, pc)
    bump = (w > 0.5) & (np.abs(generic.skin.vertices[:, 0]) < 0.002)
    before = np.linalg.norm(head.skin.vertices - person.skin.vertices, axis=1)[bump]
    after = np.linalg.norm(out.skin.vertices - person.skin.vertices, axis=1)[bump]
    assert np.median(before) > 1.5e-3
    # Measured 0.46 of the error left (0.33 when the bump sat between 8.2 and 2.1, 30 mm
    # apart, before 2.10 moved from the lip's underside to the chin boss: now 17 mm lie
    # between the held points over the sulcus, room for four controls 3 mm apart and 3 mm
    # clear of the points, and the bump is narrower to stay clear of both).
    assert np.median(after) < 0.55 * np.median(before), (np.median(before), np.median(after))
    # The feature points stay where they were put, the eyes and teeth too; the head
    # elsewhere is the same.
    assert max(np.linalg.norm(out.fp_position(i) - head.fp_position(i)) for i in targets) < 1e-6
    for name in ("eye_l", "eye_r", "teeth_upper", "tongue"):
        assert np.array_equal(out.parts[name].vertices, head.parts[name].vertices)
    far = np.linalg.norm(generic.skin.vertices - person.fp_position("2.1"), axis=1) > 0.05
    assert np.abs(out.skin.vertices[far] - head.skin.vertices[far]).max() < 0.3e-3
    # Two rounds take most of what one leaves between the controls.
    twice = match_profile(head, mask, cam, pts)
    rounds = twice.metadata["fit"]["profile"]["rounds"]
    assert len(rounds) == 2 and rounds[1]["mean_move_mm"] < 0.6 * rounds[0]["mean_move_mm"]
    again = np.linalg.norm(twice.skin.vertices - person.skin.vertices, axis=1)[bump]
    assert np.median(again) <= np.median(after) + 0.1e-3


def test_an_outline_that_is_not_the_face_is_left_out(generic):
    """A hand (or glasses, a fringe) in front of the chin in the photo: far beyond what a
    profile can differ by, so those rows are left out, not followed."""
    mask, cam, pts = _side_view(generic)
    chin = cam.project(generic.fp_position("2.1")[None])[0]
    lip = cam.project(generic.fp_position("8.2")[None])[0]
    blocked = mask.copy()
    towards = 1 if cam.project(generic.fp_position("9.3")[None])[0][0] > chin[0] else -1
    r0, r1 = int(lip[1]), int(chin[1])
    c = int(chin[0])
    if towards > 0:
        blocked[r0:r1, c:c + 60] = True  # 20 mm out
    else:
        blocked[r0:r1, c - 60:c] = True
    pc = profile_controls(generic, blocked, cam, pts)
    assert pc.left_out > 0
    assert np.abs(pc.shift_mm).max() < 0.35


def _crease(head):
    """The largest change of the skin's slope (dz/dx) across the midline at three heights
    over the mentolabial sulcus: a fold along the midline shows as a jump of the slope."""
    v = head.skin.vertices
    y0 = 0.5 * (head.fp_position("8.2")[1] + head.fp_position("2.10")[1])
    out = []
    for dy in (-2e-3, 0.0, 2e-3):
        row = np.flatnonzero((np.abs(v[:, 1] - (y0 + dy)) < 0.8e-3) & (v[:, 2] > 0.09) & (np.abs(v[:, 0]) < 0.012))
        x, z = v[row, 0], v[row, 2]
        left, right = (x < -0.5e-3) & (x > -6e-3), (x > 0.5e-3) & (x < 6e-3)
        out.append(abs(np.polyfit(x[left], z[left], 1)[0] - np.polyfit(x[right], z[right], 1)[0]))
    return max(out)


def test_the_profile_moves_no_crease_into_the_midline(generic):
    # The whole profile 3 mm forward: the face comes forward smoothly across the midline
    # (as DFFD controls on the midline's vertices alone it folded the skin along it, the
    # slope's jump growing by 0.28 here and a crease down a real pair's philtrum), and
    # every feature point stays exactly where it was.
    from recon.shape.outline import ProfileControls

    mask, cam, pts = _side_view(generic)
    pc = profile_controls(generic, mask, cam, pts)
    forward = ProfileControls(pc.vertices, pc.rest, pc.rest + [0.0, 0.0, 0.003], np.full(len(pc.rest), 3.0))
    out = follow_profile(generic, forward)
    assert _crease(out) <= _crease(generic) + 0.05, (_crease(generic), _crease(out))
    moved = out.skin.vertices[pc.vertices, 2] - generic.skin.vertices[pc.vertices, 2]
    assert np.median(moved) > 1.5e-3  # the held points take some of it back near them
    assert max(np.linalg.norm(out.fp_position(i) - generic.fp_position(i)) for i in generic.feature_points) < 1e-6
