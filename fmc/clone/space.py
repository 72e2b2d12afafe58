"""The alignment space of Facial Motion Cloning: a cylindrical projection of the head.

A point's coordinates are its angle about a vertical axis (radians, 0 at the nose tip,
positive towards the face's own left), its height above the chin in units of the chin-to-
brow height, and its distance from the axis (metres), the depth used to choose between
surfaces that project onto one another. The axis sits behind the mouth, at the depth
where the two mouth corners span :data:`MOUTH_SPAN` radians, so a wide mouth and a narrow
one cover the same angle [1]_.

References
----------
.. [1] I. S. Pandžić, "Facial motion cloning", Graphical Models 65(6) (2003) 385-404.
"""

from __future__ import annotations

import numpy as np

from mpeg4.head import Head

__all__ = ["MOUTH_SPAN", "SPACE_FPS", "cylinder_axis", "alignment_space"]

#: The mouth's angular width in the alignment space (radians).
MOUTH_SPAN = 0.5

#: Feature points the space is built from: mouth corners, nose tip, chin, inner brows.
SPACE_FPS = ("8.3", "8.4", "9.3", "2.1", "4.1", "4.2")


def cylinder_axis(mouth_left: np.ndarray, mouth_right: np.ndarray, span: float = MOUTH_SPAN) -> tuple[float, float]:
    """(x, z) of the vertical axis, metres: midway between the mouth corners in x, and at
    the depth behind them where they are ``span`` radians apart.

    Examples
    --------
    >>> x, z = cylinder_axis(np.array([0.025, 0.0, 0.1]), np.array([-0.025, 0.0, 0.1]))
    >>> round(x, 6), round(float(2 * np.arctan2(0.025, 0.1 - z)), 6)
    (0.0, 0.5)
    """
    cx = 0.5 * (mouth_left[0] + mouth_right[0])

    def angle(cz):
        return abs(np.arctan2(mouth_left[0] - cx, mouth_left[2] - cz) - np.arctan2(mouth_right[0] - cx, mouth_right[2] - cz))

    # The span grows as the axis nears the mouth: bisect on the axis depth.
    lo, hi = min(mouth_left[2], mouth_right[2]) - 1.0, min(mouth_left[2], mouth_right[2]) - 1e-4
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if angle(mid) < span else (lo, mid)
    return float(cx), float(0.5 * (lo + hi))


def alignment_space(head: Head, points: np.ndarray) -> np.ndarray:
    """(K, 3) angle (rad), height (face heights) and radius (m) of ``points`` (K, 3).

    Parameters
    ----------
    head : Head
        With the :data:`SPACE_FPS`; its neutral feature points fix the axis, the zero
        angle and the height unit.
    points : (K, 3) float
        Metres, in the head's frame.
    """
    cx, cz = cylinder_axis(head.fp_position("8.3"), head.fp_position("8.4"))
    nose = head.fp_position("9.3")
    zero = np.arctan2(nose[0] - cx, nose[2] - cz)
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    theta = np.arctan2(p[:, 0] - cx, p[:, 2] - cz) - zero
    theta = (theta + np.pi) % (2 * np.pi) - np.pi
    radius = np.hypot(p[:, 0] - cx, p[:, 2] - cz)
    y0 = head.fp_position("2.1")[1]
    h = 0.5 * (head.fp_position("4.1")[1] + head.fp_position("4.2")[1]) - y0
    return np.c_[theta, (p[:, 1] - y0) / h, radius]
