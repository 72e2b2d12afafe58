"""Coarticulated visemes: the Cohen–Massaro dominance model over a phoneme sequence.

Each phoneme ``i`` has a viseme target and a dominance that rises and falls around its
centre, ``D_i(t) = α · exp(−θ · max(0, |t − centre_i| − h_i)^c)`` (``h_i`` a quarter of the
phoneme's duration: a short plateau over its middle half, which keeps D continuous); at every instant each viseme's
intensity is ``63 · Σ_{i: viseme_i = v} D_i(t) / Σ_i D_i(t)``, a convex mixture of the
phonemes' mouth shapes. The four groups below set how strongly and how long a phoneme
holds the mouth: plosives (p b m, t d, k g) are strong and brief, so a bilabial closes
the lips even between two open vowels; vowels are weaker and spread wide, so their
shapes carry into neighbouring consonants; fricatives and the other consonants sit
between. ``c`` = 1 gives the classic exponential.

References
----------
.. [1] M. M. Cohen and D. W. Massaro, "Modeling coarticulation in synthetic visual
   speech", in Models and Techniques in Computer Animation, Springer (1993).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mpeg4.io.fap import FapStream

__all__ = ["Dominance", "GROUPS", "group_of", "viseme_weights", "speech_stream"]


@dataclass(frozen=True)
class Dominance:
    """Dominance of one group: magnitude α, rate θ (1/s), exponent c."""

    alpha: float
    theta: float
    c: float = 1.0


#: Viseme group → dominance. Chosen so that a plosive's own shape holds > 95 % of the mix
#: at its centre between open vowels (tests/fmc/test_speech.py checks the lip closure).
GROUPS = {
    "plosive": Dominance(2.0, 70.0),
    "fricative": Dominance(1.2, 50.0),
    "consonant": Dominance(0.8, 45.0),
    "vowel": Dominance(0.5, 50.0),
    "neutral": Dominance(0.3, 40.0),
}

_GROUP_OF_VISEME = {0: "neutral", 1: "plosive", 4: "plosive", 5: "plosive", 2: "fricative", 3: "fricative",
                    6: "fricative", 7: "fricative", 8: "consonant", 9: "consonant"}


def group_of(viseme: int) -> str:
    """The dominance group of a viseme (10–14 are vowels)."""
    return _GROUP_OF_VISEME.get(viseme, "vowel")


def viseme_weights(phonemes, times: np.ndarray, groups=GROUPS) -> np.ndarray:
    """(T, 15) viseme intensities (0..63, rows summing to 63) at ``times`` (seconds).

    Parameters
    ----------
    phonemes : sequence of fmc.speech.Phoneme
        With ``start``, ``end`` (s) and ``viseme``.
    times : (T,) float
    """
    times = np.asarray(times, dtype=np.float64).reshape(-1)
    dom = np.zeros((len(times), 15))
    for p in phonemes:
        g = groups[group_of(p.viseme)]
        # A plateau over the middle half of the segment, then the exponential fall-off:
        # short phonemes keep their shape for a moment, and D stays continuous.
        half = 0.25 * (p.end - p.start)
        d = g.alpha * np.exp(-g.theta * np.maximum(0.0, np.abs(times - p.centre) - half) ** g.c)
        dom[:, p.viseme] += d
    total = dom.sum(axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(total > 0, 63.0 * dom / total, 0.0)
    out[total[:, 0] == 0, 0] = 63.0
    return out


def speech_stream(phonemes, duration: float, fps: float = 50.0, name: str = "speech") -> FapStream:
    """A FAP stream of the coarticulated visemes (the two strongest per frame, as the
    ``.fap`` format's viseme field holds two with a blend).

    50 frames per second by default: a plosive lasts 30–40 ms, and at 25 fps its closure
    can fall between two frames.
    """
    n = int(np.ceil(duration * fps)) + 1
    times = np.arange(n) / fps
    w = viseme_weights(phonemes, times)
    order = np.argsort(-w, axis=1)
    v1, v2 = order[:, 0], order[:, 1]
    w1, w2 = w[np.arange(n), v1], w[np.arange(n), v2]
    blend = np.where(w1 + w2 > 0, 63.0 * w1 / (w1 + w2), 63.0)
    vis = np.c_[v1, v2, np.round(blend, 3), np.zeros(n)]
    return FapStream(fps, np.arange(n), np.full((n, 68), np.nan), viseme=vis, name=name)
