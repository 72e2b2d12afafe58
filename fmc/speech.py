"""Text to phonemes with timings and audio, offline, with espeak-ng.

espeak-ng (Debian package ``espeak-ng``) is driven through its C library with ctypes: its
phoneme events carry each phoneme's position in the audio it synthesises, so the
phonemes and the sound line up exactly. Phonemes are espeak's own mnemonics (``p``, ``a``,
``eI``, ``_:`` …); :data:`PHONEME_VISEMES` (from ``fmc/data/phoneme_visemes.toml``) maps
them to the 15 MPEG-4 visemes.
"""

from __future__ import annotations

import ctypes
import functools
import os
import threading
import unicodedata
import wave
from dataclasses import dataclass

import numpy as np

from mpeg4.errors import InputError
from mpeg4.io.atomic import atomic_write

__all__ = ["Phoneme", "Utterance", "PHONEME_VISEMES", "STOPS", "viseme_of", "stop_closures", "synthesize",
           "write_wav"]

#: The bilabial stops: the lips close in the silence before the burst.
STOPS = ("p", "b")


@dataclass(frozen=True)
class Phoneme:
    """One phoneme: espeak's mnemonic, its start and end in seconds, its MPEG-4 viseme, and
    for a stop whose closure the audio shows, when the burst releases it (the phoneme then
    starts where its silence starts, see :func:`stop_closures`)."""

    symbol: str
    start: float
    end: float
    viseme: int
    burst: float | None = None

    @property
    def centre(self) -> float:
        return 0.5 * (self.start + self.end)


@dataclass
class Utterance:
    """Synthesised speech: the text, its phonemes and its audio (int16 mono)."""

    text: str
    phonemes: list[Phoneme]
    audio: np.ndarray
    rate: int

    @property
    def duration(self) -> float:
        return len(self.audio) / self.rate


def _load_table() -> dict[str, int]:
    import tomllib
    from importlib import resources

    data = tomllib.loads(resources.files("fmc").joinpath("data/phoneme_visemes.toml").read_text())
    out = {}
    for viseme, symbols in data["visemes"].items():
        for s in symbols:
            out[s] = int(viseme)
    return out


#: espeak-ng phoneme mnemonic → MPEG-4 viseme number.
PHONEME_VISEMES = _load_table()


def viseme_of(symbol: str) -> int:
    """The viseme of an espeak phoneme; stress marks and length marks are ignored; an
    unknown symbol is neutral (0)."""
    s = symbol.strip("'\u02c8\u02cc,")
    if s in PHONEME_VISEMES:
        return PHONEME_VISEMES[s]
    if s.rstrip(":") in PHONEME_VISEMES:
        return PHONEME_VISEMES[s.rstrip(":")]
    # Diphthongs and clusters: their first symbol shapes the mouth first.
    for n in (2, 1):
        if s[:n] in PHONEME_VISEMES:
            return PHONEME_VISEMES[s[:n]]
    return 0


class _EventId(ctypes.Union):
    _fields_ = [("number", ctypes.c_int), ("name", ctypes.c_char_p), ("string", ctypes.c_char * 8)]


class _Event(ctypes.Structure):
    _fields_ = [("type", ctypes.c_int), ("unique_identifier", ctypes.c_uint), ("text_position", ctypes.c_int),
                ("length", ctypes.c_int), ("audio_position", ctypes.c_int), ("sample", ctypes.c_int),
                ("user_data", ctypes.c_void_p), ("id", _EventId)]


_CALLBACK = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.POINTER(ctypes.c_short), ctypes.c_int, ctypes.POINTER(_Event))
_EVENT_PHONEME, _EVENT_END_OF_LIST = 7, 0
_AUDIO_OUTPUT_SYNCHRONOUS = 2
_INITIALIZE_PHONEME_EVENTS, _INITIALIZE_DONT_EXIT = 0x0001, 0x8000
_LOCK = threading.Lock()  # the library keeps global state


@functools.lru_cache(maxsize=1)
def _library():
    try:
        lib = ctypes.CDLL("libespeak-ng.so.1")
    except OSError:
        raise InputError("the espeak-ng speech library is not installed",
                         fix="install the Debian package espeak-ng (bash install.sh does)") from None
    rate = lib.espeak_Initialize(_AUDIO_OUTPUT_SYNCHRONOUS, 0, None,
                                 _INITIALIZE_PHONEME_EVENTS | _INITIALIZE_DONT_EXIT)
    if rate <= 0:
        raise InputError("espeak-ng could not start (no voice data?)", fix="reinstall the Debian package espeak-ng")
    lib.espeak_Synth.argtypes = [ctypes.c_char_p, ctypes.c_size_t, ctypes.c_uint, ctypes.c_int, ctypes.c_uint,
                                 ctypes.c_uint, ctypes.c_void_p, ctypes.c_void_p]
    lib.espeak_SetVoiceByName.argtypes = [ctypes.c_char_p]
    return lib, rate


def _check_text(text: str) -> str:
    if not isinstance(text, str) or not text.strip():
        raise InputError("the text to speak is empty", fix='give a sentence, e.g. "Hello there"')
    for k, ch in enumerate(text):
        cat = unicodedata.category(ch)
        if cat.startswith("C") and ch not in "\t\n":
            raise InputError(f"character {k + 1} of the text is a control character ({ch!r})",
                             fix="remove it; the speech engine reads letters, digits and punctuation")
    if not any(unicodedata.category(ch)[0] in "LN" for ch in text):
        raise InputError(f"the text {text!r} has no letters or digits to speak", fix="give words")
    return text


def synthesize(text: str, voice: str = "en") -> Utterance:
    """Speak ``text`` with espeak-ng: its phonemes with times and the audio.

    Parameters
    ----------
    text : str
        What to say.
    voice : str
        espeak-ng voice name (``en``, ``en-us``, ``de``, …).

    Returns
    -------
    Utterance
    """
    text = _check_text(text)
    lib, rate = _library()
    samples: list[np.ndarray] = []
    events: list[tuple[int, str]] = []

    def callback(wav, n, ev):
        if wav and n > 0:
            samples.append(np.ctypeslib.as_array(wav, shape=(n,)).copy())
        i = 0
        while ev[i].type != _EVENT_END_OF_LIST:
            if ev[i].type == _EVENT_PHONEME:
                events.append((ev[i].sample, bytes(ev[i].id.string).split(b"\0")[0].decode("ascii", "replace")))
            i += 1
        return 0

    cb = _CALLBACK(callback)
    with _LOCK:
        if lib.espeak_SetVoiceByName(voice.encode()) != 0:
            raise InputError(f"espeak-ng has no voice '{voice}'", fix="try en, en-us, de, fr (espeak-ng --voices)")
        lib.espeak_SetSynthCallback(cb)
        data = text.encode("utf-8")
        err = lib.espeak_Synth(data, len(data) + 1, 0, 1, 0, 1, None, None)  # character positions, UTF-8
        lib.espeak_Synchronize()
    if err != 0:
        raise InputError(f"espeak-ng rejected the text (error {err})", fix="simplify the text")
    audio = np.concatenate(samples) if samples else np.zeros(0, np.int16)
    total = len(audio) / rate
    phonemes = []
    for k, (sample, symbol) in enumerate(events):
        start = sample / rate
        end = events[k + 1][0] / rate if k + 1 < len(events) else total
        if end > start:
            phonemes.append(Phoneme(symbol, start, end, viseme_of(symbol)))
    audio = audio.astype(np.int16)
    return Utterance(text, stop_closures(phonemes, audio, rate), audio, rate)


def stop_closures(phonemes: list[Phoneme], audio: np.ndarray, rate: int, window: float = 0.005,
                  search: float = 0.15) -> list[Phoneme]:
    """Phonemes with each bilabial stop (:data:`STOPS`) spanning its closure.

    espeak-ng's phoneme event for a stop comes at its burst; the lips have been closed
    through the silence before it, which the audio shows and the previous phoneme's span
    holds. For each stop, the run of silent windows (RMS under 3 % of the utterance's
    95th percentile) that ends within two windows of the event and starts at most
    ``search`` seconds before it becomes the stop's closure: the stop starts where the
    silence starts (the phoneme before it ends there) and records the burst. A stop with
    no silence before it (inside a word, voiced) is left as it is.

    Parameters
    ----------
    phonemes : list of Phoneme
    audio : (S,) int16
    rate : int
        Samples per second.
    window, search : float
        Seconds.
    """
    w = max(1, int(round(window * rate)))
    n = len(audio) // w
    if n == 0:
        return list(phonemes)
    rms = np.sqrt(np.mean(audio[:n * w].astype(np.float64).reshape(n, w) ** 2, axis=1))
    silent = rms < 0.03 * max(float(np.percentile(rms, 95)), 1.0)
    out = list(phonemes)
    for k, p in enumerate(out):
        if p.symbol not in STOPS or k == 0:
            continue  # (before the first phoneme, the silence is the start of the audio)
        j = min(int(p.start * rate) // w, n) - 1  # the window before the event
        while j >= 0 and not silent[j] and (p.start - j * w / rate) <= 2 * window + 1e-9:
            j -= 1  # the silence may end a window or two before the event
        if j < 0 or not silent[j]:
            continue
        end = j
        while j > 0 and silent[j - 1] and p.start - (j - 1) * w / rate <= search:
            j -= 1
        start, burst = j * w / rate, (end + 1) * w / rate
        prev = out[k - 1]
        if prev.start >= start or not prev.viseme:
            continue  # the silence is a pause, not this stop's closure
        out[k] = Phoneme(p.symbol, start, p.end, p.viseme, burst=min(max(burst, start), p.end))
        out[k - 1] = Phoneme(prev.symbol, prev.start, start, prev.viseme, prev.burst)
    return out


def write_wav(utterance: Utterance, path) -> str:
    """The utterance's audio as a 16-bit mono WAV (atomic write)."""
    import io

    buf = io.BytesIO()
    with wave.open(buf, "wb") as w:
        w.setnchannels(1)
        w.setsampwidth(2)
        w.setframerate(utterance.rate)
        w.writeframes(utterance.audio.astype("<i2").tobytes())
    with atomic_write(path, "wb") as f:
        f.write(buf.getvalue())
    return os.fspath(path)
