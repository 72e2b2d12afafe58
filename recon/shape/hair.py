"""The skull under the hair: where the top and back of the head lie when a photo's outline
there is hair.

A photo's outline of the top and the back of the head is the hair's, not the skull's. Of
what the outline tells, the skull takes only what hair cannot explain. Along the skull's
outward normal, with ``d`` the outline's distance out from where the face's points put
the skull (the generic head carried by them, :func:`recon.shape.calibrate.calibrate`):

- the skull lies at ``delta`` out from that guess, ``delta ~ N(0, SKULL_SD_MM²)``: the
  spread of a skull about a face of a given size and shape. Heads drawn from the shipped
  identity model (50 ICT modes) put the top of the skull (11.4) 5.0 mm (RMS along the
  normal, 450 heads) from that guess and the back (11.6) 5.5 mm
  (``tests/recon/test_hair.py`` measures it again); the modes it leaves out add a little;
- the hair over it is ``t = d - delta >= 0`` thick, exponentially distributed with mean
  :data:`HAIR_MEAN_MM`: most hair on the crown is a centimetre or two thick and some far
  more (bushy, curly, pinned up), none less than nothing.

The skull is taken at the posterior mean of ``delta`` given ``d`` (:func:`skull_offset`):
``delta | d`` is normal with mean ``mu = SKULL_SD² / HAIR_MEAN`` and the skull's spread,
truncated at ``d`` (the skull is never outside the outline). With a thick head of hair the
skull stays near the guess (``mu``, 1.7 mm out); with thin hair, where the outline is close
to the guess, it follows the outline; an outline inside the guess is a small skull, taken
as it is. Where the outline is skin (a bald crown) it is the skull's, and none of this
applies.
"""

from __future__ import annotations

import numpy as np
from scipy.special import log_ndtr

from mpeg4.head import Head

__all__ = ["SKULL_SD_MM", "HAIR_MEAN_MM", "UNDER_HAIR", "skull_offset", "skull_under", "skull_normals"]

#: Spread (mm, one standard deviation along the normal) of the skull's top and back about
#: where a face's points put them.
SKULL_SD_MM = 5.0
#: Mean thickness (mm) of the hair over the crown and the back of the head (exponential).
HAIR_MEAN_MM = 15.0
#: The points whose outline can be hair's: the top (11.4) and back (11.6) of the skull.
UNDER_HAIR = ("11.4", "11.6")


def skull_offset(outline_mm, skull_sd_mm: float = SKULL_SD_MM, hair_mean_mm: float = HAIR_MEAN_MM) -> np.ndarray:
    """Posterior mean of the skull's distance out from its guess, given the outline's.

    Parameters
    ----------
    outline_mm : float or (K,) array
        How far out along the skull's normal the photo's outline lies from the guess, mm
        (negative: inside it).
    skull_sd_mm, hair_mean_mm : float
        The skull's spread about the guess and the hair's mean thickness (see the module).

    Returns
    -------
    (K,) float64 or float
        Millimetres out from the guess; never more than ``outline_mm``.
    """
    d = np.asarray(outline_mm, dtype=np.float64)
    s = float(skull_sd_mm)
    mu = s * s / float(hair_mean_mm)
    a = (d - mu) / s
    # Mean of N(mu, s²) truncated above at d: mu - s φ(a) / Φ(a), the ratio in logs so
    # that an outline far inside the guess (a → -∞) stays finite (the ratio tends to -a).
    ratio = np.exp(-0.5 * a * a - 0.5 * np.log(2 * np.pi) - log_ndtr(a))
    out = np.minimum(mu - s * ratio, d)
    return out if out.ndim else float(out)


def skull_under(guess: np.ndarray, outline: np.ndarray, normal: np.ndarray, across_limit: float = np.inf) -> np.ndarray:
    """(3,) where the skull lies under a hair outline, metres: from ``guess`` (where the
    face's points put it), across the ``normal`` as far as the ``outline`` point (at most
    ``across_limit``), along it by :func:`skull_offset` of the outline's distance out."""
    d = np.asarray(outline, float) - np.asarray(guess, float)
    n = np.asarray(normal, float)
    out = float(d @ n)
    across = d - out * n
    k = float(np.linalg.norm(across))
    if k > across_limit:
        across *= across_limit / k
    return guess + across + skull_offset(out * 1000.0) / 1000.0 * n


def skull_normals(head: Head) -> dict[str, np.ndarray]:
    """FP id → (3,) unit outward normal of ``head``'s surface at each of its
    :data:`UNDER_HAIR` points (the normals of the vertices it is bound to, weighted;
    absent where the part has no triangles there)."""
    from mpeg4.render import vertex_normals

    out = {}
    cache = {}
    for i in UNDER_HAIR:
        b = head.feature_points.get(i)
        if b is None:
            continue
        if b.part not in cache:
            part = head.parts[b.part]
            cache[b.part] = vertex_normals(part.vertices, part.triangles)
        n = np.asarray(b.weights) @ cache[b.part][list(b.vertices)]
        if np.linalg.norm(n) > 1e-12:  # a point on no triangle has no normal
            out[i] = n / np.linalg.norm(n)
    return out
