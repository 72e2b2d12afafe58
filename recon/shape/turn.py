"""The head's turn in a front photo, read from its midline against the side photo's depths.

Booking photos and selfies are often turned 5-20 degrees. A front photo's x then mixes each
point's depth into its x (``x cos + z sin``), and a head built on it is sheared: the ears
of one real pair came out 61 and 101 mm from the midline. :func:`front_turn` reads the turn
from where the face's midline lies at each depth, :func:`generic_depths` gives every point
a depth for taking it out, and :func:`too_turned` is the error for a front photo turned
past :data:`MAX_TURN_DEG`. Used by :mod:`recon.shape.calibrate`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from mpeg4.catalogue import FEATURE_POINTS
from mpeg4.errors import InputError
from mpeg4.head import Head

from .core_points import is_core

__all__ = ["TURN_NOISE_DEG", "MAX_TURN_DEG", "front_turn", "generic_depths", "too_turned"]


#: Turns of the front photo (degrees) within which the face is taken as photographed from
#: the front: a face's own asymmetry drifts its midline with depth too. On twelve
#: synthetic people photographed exactly from the front (ICT FaceKit identities, scans of
#: real faces) the drift read as turns of -2.4 to +1.2 degrees (sd 1.1), and taking them out
#: made the points' x worse (0.25 -> 0.61 mm mean on five). Beyond it the turn is taken
#: out in a ramp, fully from twice as far (continuous, so no threshold decides a head).
TURN_NOISE_DEG = 3.0
#: A front photo turned further than this (degrees) is refused: the far side of the face
#: hides behind the nose, and its points are guesses (the detection refuses such photos
#: too; this holds for points given by hand).
MAX_TURN_DEG = 30.0


def too_turned(sin_yaw: float) -> InputError:
    """The error for a front photo turned past :data:`MAX_TURN_DEG` (``sin_yaw``: its sine)."""
    deg = float(np.degrees(np.arcsin(sin_yaw)))
    return InputError(f"the face in the front photo is turned {abs(deg):.0f} degrees to its "
                      f"{'left' if deg > 0 else 'right'} (more than {MAX_TURN_DEG:g})", where="front view",
                      fix="take the front photo with the face looking into the camera, or check the points of "
                          "the face's midline and of its eyes and mouth in both photos")


def front_turn(x: Mapping[str, float], z: Mapping[str, float], weight: Mapping[str, float] | None = None,
               noise_deg: float = TURN_NOISE_DEG, max_deg: float = MAX_TURN_DEG) -> tuple[float, float]:
    """The head's turn in the front photo, from where its midline lies there at each depth.

    A face turned by ``yaw`` about the vertical shows a point at ``x cos(yaw) + z sin(yaw)``
    across the photo: the midline's points and the middles of mirrored pairs (x = 0) lie
    on a line ``x0 + z sin(yaw)`` against their depth, which the side photo gives. Only the
    face's core points count (:func:`is_core`: eyes, nose, mouth, chin; the face mesh
    places them within a millimetre or two of each other): the skull's outline is the
    hair's, which need not be centred on the skull (on one real pair the top of the hair
    held a 12 degree turn to 1), and the ears are often guessed. The line is fitted
    robustly (Huber weights at 1.5 times the residuals' scale), so that one point placed
    on the cheek does not turn the head.

    Parameters
    ----------
    x : mapping of FP id to float
        Positions across the front photo, metres (scaled by the pupils, centre anywhere).
    z : mapping of FP id to float
        Depths, metres (+z towards the front camera), for the same ids.
    weight : mapping of FP id to float, optional
        Each point's weight (default 1). :func:`recon.shape.calibrate.calibrate` gives
        none: confidences speak of where a point lies, not of the midline, and a point
        placed by hand (1) among guesses (0) would turn the head alone.
    noise_deg : float
        Turns read within it are not taken out; from ``noise_deg`` to twice it, taken out
        in a linear ramp (:data:`TURN_NOISE_DEG`).
    max_deg : float
        A turn read past it is an error (:func:`too_turned`, :data:`MAX_TURN_DEG`).

    Returns
    -------
    sin_yaw : float
        The turn to take out: positive when the face turned towards its own left (the
        image's right); 0 when the points' depths span less than 3 cm or fewer than four
        lines of evidence exist.
    x0 : float
        Where the midline crosses depth 0 with that turn, metres.
    """
    weight = weight or {}
    rows = []  # (x of the midline, z, weight)
    for i, v in x.items():
        fp = FEATURE_POINTS[i]
        if not is_core(i):
            continue
        if fp.side == "C" and i in z:
            rows.append((v, z[i], weight.get(i, 1.0)))
        elif fp.side == "L" and fp.mirror in x and i in z and fp.mirror in z:
            rows.append((0.5 * (v + x[fp.mirror]), 0.5 * (z[i] + z[fp.mirror]),
                         min(weight.get(i, 1.0), weight.get(fp.mirror, 1.0))))
    if not rows:  # no depths for the core: the midline from every point, unturned
        mids = [v for i, v in x.items() if FEATURE_POINTS[i].side == "C"]
        mids += [0.5 * (v + x[FEATURE_POINTS[i].mirror]) for i, v in x.items()
                 if FEATURE_POINTS[i].side == "L" and FEATURE_POINTS[i].mirror in x]
        return 0.0, float(np.mean(mids)) if mids else 0.0
    m, d, w = (np.array(c, dtype=np.float64) for c in zip(*rows))
    w = np.clip(w, 1e-3, None)
    if len(rows) < 4 or np.ptp(d) < 0.03:
        return 0.0, float(np.average(m, weights=w))
    A = np.c_[np.ones_like(d), d]
    h = w.copy()
    for _ in range(20):
        (x0, slope), *_ = np.linalg.lstsq(A * np.sqrt(h)[:, None], m * np.sqrt(h), rcond=None)
        r = m - A @ [x0, slope]
        scale = 1.4826 * np.median(np.abs(r))
        if scale < 1e-9:
            break
        h = w * np.minimum(1.0, 1.5 * scale / np.maximum(np.abs(r), 1e-12))
    deg = np.degrees(np.arcsin(np.clip(slope, -0.9, 0.9)))
    if abs(deg) > max_deg:
        raise too_turned(float(np.sin(np.radians(deg))))
    taken = deg * np.clip((abs(deg) - noise_deg) / max(noise_deg, 1e-9), 0.0, 1.0)
    sin_yaw = float(np.sin(np.radians(taken)))
    return sin_yaw, float(np.average(m - sin_yaw * d, weights=h))


def generic_depths(x: Mapping[str, float], z: Mapping[str, float], generic: Head) -> dict[str, float]:
    """A depth for each id of ``x``: the side photo's, else its mirror partner's, else the
    generic head's shifted to the side photo's depths. A point the side photo cannot give
    needs its depth only roughly: for the turn's share of its x, and under perspective
    for its distance from the front camera (at depth 0, the side camera's axis, the inner
    eye corners and brows came out 2-3.5 mm too high)."""
    g = {i: float(generic.fp_position(i)[2]) for i in generic.feature_points}
    both = [i for i in z if i in g]
    shift = float(np.mean([z[i] - g[i] for i in both])) if both else 0.0
    out = {}
    for i in x:
        m = FEATURE_POINTS[i].mirror
        out[i] = z[i] if i in z else z[m] if m in z else g.get(i, g.get(m, shift) - shift) + shift
    return out
