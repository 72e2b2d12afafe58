"""Which way a profile photo faces, from independent cues, with a confidence.

A profile's silhouette alone is easily read backwards: a ponytail, bushy hair or a dark
background out-bumps the nose. :func:`profile_facing` weighs three cues that fail in
different ways:

- **the face detector** (:func:`recon.landmarks.models.face_keypoints`): where the nose tip
  lies against the ear tragions it finds — the face's own features, not the outline;
- **the profile fit** (:func:`recon.landmarks.profile.fit_profile`): the front photo's face
  mesh midline laid on the silhouette facing each way; a forehead, nose, lips and chin fit
  only the face's side, not the back of the head or a ponytail;
- **skin at the edges**: the front photo's skin colour found just inside the silhouette's
  face-side edge (forehead, cheek, lips, chin), where the back of the head shows hair;
- **the outline's bumps** (:func:`recon.landmarks.side.facing_of`'s measure): the nose is a
  sharper bump than the back of a bare head; the weakest cue, counted half.

Each cue votes in [-1, 1] (positive: the nose towards the image's left); the confidence is
the weighted vote's share of the weights of the cues that could vote. Callers refuse an
unsure facing rather than read the profile backwards in silence (:data:`SURE`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mpeg4.errors import InputError

__all__ = ["SURE", "AGREE", "Facing", "UnsureFacing", "profile_facing", "silhouette_vote", "skin_vote",
           "detector_vote", "fit_vote"]

#: Below this confidence the facing is not taken without the user saying it
#: (``--side-facing``); between it and :data:`AGREE`, taken with a warning.
SURE = 0.25
#: At or above this confidence, and no cue against it, the facing is taken silently.
AGREE = 0.5
#: Weights of the cues: the detector and the profile fit look at the face, the outline's
#: bumps only at the silhouette.
WEIGHTS = {"detector": 1.0, "profile": 1.0, "skin": 1.0, "outline": 0.5}


@dataclass
class Facing:
    """Where the nose points in a profile photo.

    Attributes
    ----------
    facing : {"left", "right"}
    confidence : float
        In [0, 1]: the weighted vote's share of the weights that voted.
    votes : dict of str to float
        Each cue's vote in [-1, 1] (positive: left); a cue that could not vote is absent.
    given : bool
        True when the user gave the facing (``--side-facing``).
    """

    facing: str
    confidence: float
    votes: dict[str, float] = field(default_factory=dict)
    given: bool = False

    @property
    def against(self) -> list[str]:
        """The cues that voted for the other facing."""
        sign = 1.0 if self.facing == "left" else -1.0
        return [k for k, v in self.votes.items() if v * sign < -0.05]

    def record(self) -> dict:
        """What an annotation file's ``metadata["landmarks"]["side_facing"]`` keeps of it."""
        return {"facing": self.facing, "confidence": round(self.confidence, 3),
                "votes": {k: round(v, 3) for k, v in self.votes.items()}, "given": self.given}

    def describe(self) -> str:
        if self.given:
            return f"facing {self.facing} (given)"
        votes = ", ".join(f"{k} {'left' if v > 0 else 'right'} {abs(v):.2f}" for k, v in self.votes.items())
        return f"facing {self.facing}, confidence {self.confidence:.2f} ({votes})"


class UnsureFacing(InputError):
    """The side photo's facing was not sure enough to take without the user saying it.

    ``found`` is the :class:`Facing` read (its ``facing`` the better guess), so that a
    caller that lets the user check it, as ``recon annotate`` does, can go on with it.
    """

    def __init__(self, found: Facing, where: str | None = None):
        self.found = found
        super().__init__(f"cannot tell which way the side photo faces ({found.describe()})", where=where,
                         fix="say where the nose points in the side photo: --side-facing left or --side-facing right")


def silhouette_vote(mask: np.ndarray) -> float:
    """(left bump − right bump) / their sum over the face's rows of a profile silhouette."""
    from .silhouette import bumpiness, row_extents

    left, right = row_extents(mask)
    rows = np.flatnonzero(np.isfinite(left))
    if len(rows) == 0:
        return 0.0
    n = len(rows)
    scale = max(2, int(0.03 * n))
    head = slice(rows[0] + int(0.15 * n), rows[0] + int(0.6 * n))
    lb, rb = bumpiness(left[head], scale), bumpiness(-right[head], scale)
    return float((lb - rb) / (lb + rb)) if lb + rb > 0 else 0.0


def skin_vote(image: np.ndarray, mask: np.ndarray, skin) -> float:
    """The share of skin-coloured pixels just inside the silhouette's left edge against its
    right edge, over the face's rows: positive when the left edge is the skin's.

    ``skin`` is a :class:`~recon.landmarks.colour.ColourModel` of the person's skin (from
    the front photo); the band is 4 % of the head's width deep.
    """
    from .colour import FAR, to_lab
    from .silhouette import row_extents

    left, right = row_extents(mask)
    rows = np.flatnonzero(np.isfinite(left))
    if len(rows) < 10:
        return 0.0
    n = len(rows)
    band = rows[int(0.2 * n):int(0.55 * n)]
    width = np.nanmedian(right[band] - left[band])
    depth = max(2, int(0.04 * width))
    lab = to_lab(image)
    shares = []
    for edge, step in ((left, 1), (right, -1)):
        cols = np.round(edge[band]).astype(int)[:, None] + step * np.arange(1, depth + 1)[None, :]
        cols = np.clip(cols, 0, mask.shape[1] - 1)
        rr = np.repeat(band[:, None], depth, axis=1)
        inside = mask[rr, cols]
        is_skin = skin.distance2(lab[rr, cols]) < FAR
        shares.append((is_skin & inside).sum() / max(inside.sum(), 1))
    total = shares[0] + shares[1]
    return float((shares[0] - shares[1]) / total) if total > 0.05 else 0.0


def detector_vote(keypoints: np.ndarray, box: np.ndarray, score: float) -> float:
    """The nose tip's place against the ear tragions, in face widths, times the detector's
    score: positive when the nose is left of the ears."""
    nose, ears = keypoints[2, 0], keypoints[4:6, 0].mean()
    return float(np.clip((ears - nose) / max(0.3 * box[2], 1e-9), -1.0, 1.0) * score)


def fit_vote(cost_left: float, cost_right: float) -> float:
    """The profile fit's relative cost difference: positive when facing left fits better."""
    total = cost_left + cost_right
    return float(np.clip(3.0 * (cost_right - cost_left) / total, -1.0, 1.0)) if total > 0 else 0.0


def profile_facing(image: np.ndarray, mask: np.ndarray, fit_costs: tuple[float, float] | None = None,
                   skin=None, given: str | None = None) -> Facing:
    """The facing of a profile photo and how sure it is.

    Parameters
    ----------
    image : (H, W, 3) uint8
        RGB profile photo as given.
    mask : (H, W) bool
        The head's silhouette in it.
    fit_costs : (float, float), optional
        The profile fit's cost facing left and facing right (the front photo's face mesh
        on ``mask`` and on its mirror image); without it that cue does not vote.
    given : {"left", "right"}, optional
        The user's word, taken as it is.

    Returns
    -------
    Facing
    """
    if given is not None:
        if given not in ("left", "right"):
            raise ValueError(f"side facing must be 'left' or 'right', not {given!r}")
        return Facing(given, 1.0, {}, given=True)
    from .models import MediapipeMissing, face_keypoints

    votes = {"outline": silhouette_vote(mask)}
    if fit_costs is not None:
        votes["profile"] = fit_vote(*fit_costs)
    if skin is not None:
        votes["skin"] = skin_vote(image, mask, skin)
    try:
        found = face_keypoints(image)
    except MediapipeMissing:
        found = None
    if found is not None:
        votes["detector"] = detector_vote(*found)
    total = sum(WEIGHTS[k] * v for k, v in votes.items())
    confidence = abs(total) / sum(WEIGHTS[k] for k in votes)
    return Facing("left" if total >= 0 else "right", float(confidence), votes)
