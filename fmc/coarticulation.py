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

from mpeg4.io.fap import LIP_CONTOUR_PAIRS, FapStream

__all__ = ["Dominance", "GROUPS", "group_of", "viseme_weights", "speech_stream", "LIP_PAIRS", "close_bilabials"]


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


#: Lip FAP pairs that close the mouth: (upper lip FAP, its FP, lower lip FAP, its FP).
LIP_PAIRS = ((4, "2.2", 5, "2.3"), (8, "2.6", 10, "2.8"), (9, "2.7", 11, "2.9"))
_CLOSING_FAPS = (4, 5, 8, 9, 10, 11, 16, 17)
#: Largest value, in MNS units, the lip closure gives a lip FAP (1024: the mouth's whole
#: height at rest, MNS0).
CLOSING_LIMIT = 1024.0


def close_bilabials(player, stream: FapStream, phonemes, iterations: int = 6) -> FapStream:
    """Make the lips meet where a bilabial (p, b, m) holds the mouth, whatever else moves it.

    An expression or an open neighbour can hold the jaw open across a bilabial; its
    viseme alone then cannot close the lips. For every frame where bilabials have a share
    ``s`` of the coarticulated mix, the inner-lip gaps are measured through the head's own
    tables and the lip FAPs (4/5, 8/10, 9/11: upper lip down, lower lip up, half each;
    16/17: lower lip forward, upper lip back) close ``s`` of the gap, vertically and in
    depth, by secant steps (the tables are piecewise linear in the values).

    Parameters
    ----------
    player : fmc.play.Player
        Of the head that will play the stream.
    stream : FapStream
        Frames numbered from 0 at ``stream.fps``; changed in place and returned.
    phonemes : sequence of fmc.speech.Phoneme
    """
    head = player.head
    mns = head.fapu.MNS0 / 1024.0
    times = stream.frame_numbers / stream.fps
    share = viseme_weights(phonemes, times)[:, 1] / 63.0
    # Through a stop's closure (its silence, up to the burst) the lips are shut, whatever
    # the coarticulation mixes in (fmc.speech.stop_closures).
    for p in phonemes:
        if getattr(p, "burst", None) is not None:
            share[(times >= p.start) & (times <= p.burst)] = 1.0
    held = stream.held()
    # Set in every frame, so no player's notion of "unset" matters; the outer-lip partners
    # too, with the inner contour's values (the whole lip closes).
    written = _CLOSING_FAPS + tuple(LIP_CONTOUR_PAIRS[f] for f in _CLOSING_FAPS if f in LIP_CONTOUR_PAIRS)
    for f in written:
        stream.values[:, f - 1] = np.nan_to_num(held.values[:, f - 1])
    for i in np.flatnonzero(share > 0.02):
        values = held.frame_values(i)
        # Secant steps on each closing pair (the tables are piecewise linear in the value,
        # so two or three steps land on the target).
        history: dict = {}
        free = None  # gaps before any closing, for this frame
        for _ in range(iterations):
            parts = player.part_vertices(player.vertices(values))
            gaps = {fu: head.fp_position(pu, parts)[1] - head.fp_position(pl, parts)[1] for fu, pu, fl, pl in LIP_PAIRS}
            gaps[16] = head.fp_position("2.2", parts)[2] - head.fp_position("2.3", parts)[2]
            if free is None:
                free = dict(gaps)
            # The lips close by the bilabial's share of the way from where the face holds
            # them to touching (no gap, same depth).
            errors = {f: gaps[f] - (1.0 - share[i]) * free[f] for f in gaps}
            for f, err in errors.items():
                v = values.get(f, 0.0)
                prev = history.get(f)
                if prev is not None and abs(err - prev[1]) > 1e-9:
                    step = -err * (v - prev[0]) / (err - prev[1])
                else:
                    step = 0.5 * err / mns
                history[f] = (v, err)
                partner = {4: 5, 8: 10, 9: 11, 16: 17}[f]
                # Bounded: a head whose tables cannot close its lips gets the best they can do
                # within one MNS0 of travel (no mouth needs more), never a runaway secant.
                new = float(np.clip(v + step, -CLOSING_LIMIT, CLOSING_LIMIT))
                step = new - v
                values[f] = new
                values[partner] = float(np.clip(values.get(partner, 0.0) + (step if f != 16 else -step),
                                                -CLOSING_LIMIT, CLOSING_LIMIT))
                for g in (f, partner):
                    if g in LIP_CONTOUR_PAIRS:
                        values[LIP_CONTOUR_PAIRS[g]] = values[g]
        for f in written:
            stream.values[i, f - 1] = values.get(f, 0.0)
    return stream
