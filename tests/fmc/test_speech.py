"""Speech: espeak-ng phonemes and audio, coarticulation, and a spoken sentence on a head."""

import shutil

import numpy as np
import pytest

from fmc.coarticulation import speech_stream, viseme_weights
from fmc.high_level import author_high_level
from fmc.play import Player
from fmc.speech import synthesize, viseme_of
from mpeg4 import InputError
from mpeg4.generic_head import load_generic_head

pytestmark = pytest.mark.skipif(shutil.which("espeak-ng") is None,
                                reason="espeak-ng is not installed (bash install.sh installs it)")


@pytest.fixture(scope="module")
def head():
    h = load_generic_head()
    h.fat = author_high_level(h)
    return h


def _lip_gap(head, player, weights):
    parts = player.part_vertices(player.vertices({(1, v): w for v, w in enumerate(weights) if w > 0}))
    return np.linalg.norm(head.fp_position("2.2", parts) - head.fp_position("2.3", parts))


def test_phonemes_line_up_with_the_audio():
    u = synthesize("Happy birthday to you.")
    assert u.rate > 8000 and 0.6 < u.duration < 2.5
    symbols = [p.symbol for p in u.phonemes]
    assert symbols[:4] == ["h", "a", "p", "i"]
    starts = [p.start for p in u.phonemes]
    assert starts == sorted(starts) and u.phonemes[-1].end <= u.duration + 1e-9
    assert [p.viseme for p in u.phonemes[1:4]] == [10, 1, 12]


def test_bilabial_closes_the_lips_between_open_vowels(head):
    u = synthesize("happy")
    p = next(x for x in u.phonemes if x.symbol == "p")
    player = Player(head)
    w = viseme_weights(u.phonemes, [p.centre, u.phonemes[1].centre])
    assert _lip_gap(head, player, w[0]) < 1e-3  # closed within 1 mm at the p
    assert _lip_gap(head, player, w[1]) > 1e-2  # open on the a before it
    # A 50 fps stream has a frame inside the closure.
    s = speech_stream(u.phonemes, u.duration)
    inside = [i for i, t in enumerate(s.frame_numbers / s.fps) if p.start <= t < p.end]
    assert inside and any(s.viseme[i, 0] == 1 and s.viseme[i, 2] > 55 for i in inside)


def test_weights_are_a_convex_mixture():
    u = synthesize("Coarticulation smooths the mouth.")
    t = np.linspace(0, u.duration, 200)
    w = viseme_weights(u.phonemes, t)
    np.testing.assert_allclose(w.sum(axis=1), 63.0)
    assert w.min() >= 0
    # Continuous: no frame-to-frame jump larger than a fraction of the range at 200 samples.
    assert np.abs(np.diff(w, axis=0)).max() < 40


def test_viseme_table():
    assert viseme_of("p") == 1 and viseme_of("u:") == 14 and viseme_of("'a") == 10 and viseme_of("zz?") == 7
    assert viseme_of("Qq") == 13 and viseme_of("") == 0


@pytest.mark.parametrize("text, message", [("", "empty"), ("   ", "empty"), ("!?..", "no letters or digits"),
                                           ("hi\x07there", "character 3 of the text is a control character")])
def test_bad_text(text, message):
    with pytest.raises(InputError, match=message):
        synthesize(text)


def test_fmc_say_writes_audio_stream_and_animation(head, tmp_path):
    import wave

    from fmc.animate import say
    from mpeg4.io import read_fap, write_glb
    from mpeg4.io.gltf import read_glb_animation

    write_glb(head, tmp_path / "h.glb")
    paths = say(tmp_path / "h.glb", "Hello.", tmp_path / "out", preview=False)
    with wave.open(str(paths["audio"])) as w:
        seconds = w.getnframes() / w.getframerate()
    stream = read_fap(paths["stream"])
    assert abs(stream.duration - seconds) < 0.05
    anim = read_glb_animation(paths["animation"])
    assert anim.times[-1] == pytest.approx((stream.n_frames - 1) / stream.fps, abs=1e-4)


@pytest.mark.parametrize("expression", [6, 1])  # surprise (jaw dropped), joy
def test_bilabial_closes_the_lips_inside_an_expression(expression):
    from fmc.author import author_from_shapes
    from fmc.coarticulation import close_bilabials

    h = load_generic_head()
    fat, _ = author_from_shapes(h)
    fat.update(author_high_level(h))
    h.fat = fat
    player = Player(h)  # the limits on: they leave a closed mouth closed
    u = synthesize("happy")
    p = next(x for x in u.phonemes if x.symbol == "p")
    s = speech_stream(u.phonemes, u.duration)
    s.expression[:] = [expression, 50, 0, 0, 0, 0]
    i = int(np.argmin(np.abs(s.frame_numbers / s.fps - p.centre)))

    def gap(stream, k):
        parts = player.part_vertices(player.vertices(stream.held().frame_values(k)))
        return np.linalg.norm(h.fp_position("2.2", parts) - h.fp_position("2.3", parts))

    assert gap(s, i) > 3e-3  # the expression alone holds the lips apart
    close_bilabials(Player(h, limits=False), s, u.phonemes)
    assert gap(s, i) < 1e-3
    a = next(x for x in u.phonemes if x.symbol == "a")
    assert gap(s, int(np.argmin(np.abs(s.frame_numbers / s.fps - a.centre)))) > 1e-2  # the vowel stays open


def test_lips_are_closed_through_each_stops_silence():
    """At every p and b after a voiced sound, the lips are closed (inner gap under 1 mm)
    for at least 80 % of the silence before its burst, found here on the audio itself;
    the closure used to follow espeak's event, which marks the release."""
    from fmc.coarticulation import close_bilabials
    from fmc.speech import STOPS

    h = load_generic_head(with_fat=True)
    u = synthesize("Bob met my papa. A cup of hot soup, please.")
    s = speech_stream(u.phonemes, u.duration, fps=200.0)  # 5 ms frames: the silences last 30-40 ms
    close_bilabials(Player(h, limits=False), s, u.phonemes)
    player = Player(h)
    held = s.held()
    times = s.frame_numbers / s.fps
    loud = np.abs(u.audio.astype(float))
    w = int(0.005 * u.rate)
    checked = 0
    for k, p in enumerate(u.phonemes):
        if p.symbol not in STOPS or k == 0 or not u.phonemes[k - 1].viseme:
            continue
        event = p.burst if p.burst is not None else p.start  # espeak's event: the burst
        quiet = []
        j = int(event * u.rate) - w
        while j > 0 and loud[j:j + w].max() < 0.03 * loud.max() and event - j / u.rate < 0.15:
            quiet.append(j / u.rate)
            j -= w
        if len(quiet) < 3:
            continue  # no silence before this one: a voiced closure
        frames = np.flatnonzero((times >= min(quiet)) & (times < max(quiet) + 0.005))
        gaps = []
        for i in frames:
            parts = player.part_vertices(player.vertices(held.frame_values(i)))
            gaps.append(np.linalg.norm(h.fp_position("2.2", parts) - h.fp_position("2.3", parts)))
        assert np.mean(np.array(gaps) < 1e-3) >= 0.8, (p, np.round(np.array(gaps) * 1e3, 2))
        checked += 1
    assert checked >= 3
