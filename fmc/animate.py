"""FAP streams to files people can play: an animated GLB and a preview GIF.

The GLB keeps the head as :func:`mpeg4.io.write_glb` writes it and adds one animation:
the weights of the morph targets that stand for the FAT's mesh tables (from
:func:`mpeg4.fat.morph_weights`, so the viewer reproduces the piecewise-linear rule inside
each interval), the eyeballs' rotations about their centres, and the head's rotation
about 7.1 (a ``pivot`` node). FaceDefTransforms a glTF node cannot carry (a translation or
a scale of a part inside the head mesh) are left out and named in the returned warnings.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from mpeg4.errors import InputError
from mpeg4.fat import _key, fap_unit, fat_to_morph_targets, morph_weights, widen_outer_borders
from mpeg4.head import Head
from mpeg4.io.fap import check_values
from mpeg4.io.gltf import GlbAnimation

from .frames import FrameDecoder

__all__ = ["covering_head", "stream_animation", "render_preview_frames", "write_gif", "write_video", "write_animation",
           "play_stream", "say", "animate_timeline"]


def covering_head(head: Head, stream, limits: bool = True) -> Head:
    """``head`` with its tables' outer borders widened to the largest values ``stream``
    plays (as :class:`fmc.frames.FrameDecoder` reads them), so that every morph weight of
    its animation stays within [0, 1] (:func:`mpeg4.fat.widen_outer_borders`): Blender, which
    clamps shape-key values to [0, 1], and three.js then play the same face."""
    import copy

    if head.fat is None or not len(head.fat):
        return head
    held = stream.held()
    decode = FrameDecoder(head, limits=limits)
    extents: dict = {}
    for i in range(held.n_frames):
        for k, v in decode(held.frame_values(i)).items():
            key = _key(k)
            lo, hi = extents.get(key, (0.0, 0.0))
            extents[key] = (min(lo, float(v)), max(hi, float(v)))
    out = copy.copy(head)
    out.fat = widen_outer_borders(head.fat, extents)
    return out


def stream_animation(head: Head, stream, limits: bool = True) -> tuple[GlbAnimation, list[str]]:
    """Keyframes of a :class:`mpeg4.io.fap.FapStream` for ``head`` (values held between frames,
    played as :class:`fmc.frames.FrameDecoder` reads them; ``limits=False`` plays them
    without the limits a face has).

    Returns
    -------
    animation : GlbAnimation
    warnings : list of str
    """
    if head.fat is None or not len(head.fat):
        raise InputError("the head has no Facial Animation Tables to play",
                         fix="author them first: fmc author HEAD -o HEAD_WITH_FAT.glb")
    check_values(stream)  # a stream made in code is checked as a file is
    held = stream.held()
    if held.n_frames == 0:
        raise InputError("the stream has no frames", fix="give a .fap file with at least one frame")
    times = (held.frame_numbers - held.frame_numbers[0]) / stream.fps
    _, specs = fat_to_morph_targets(head.fat, head.fapu)
    decode = FrameDecoder(head, limits=limits)  # the values as the player plays them
    weights = {s.target: np.zeros(held.n_frames) for s in specs}
    rotations = {}
    movers = {"pivot": None}
    for name in ("eye_l", "eye_r"):
        if name in head.parts and head.parts[name].centre is not None:
            movers[name] = name
    for node in movers:
        rotations[node] = np.tile([0.0, 0.0, 0.0, 1.0], (held.n_frames, 1))
    warnings = set()
    for i in range(held.n_frames):
        values = decode(held.frame_values(i))
        for target, w in morph_weights(specs, values).items():
            weights[target][i] = w
        mats = {node: np.eye(3) for node in movers}
        for k in sorted(values, key=_key):
            key = _key(k)
            table = head.fat.get(key)
            if table is None or not values[k]:
                continue
            unit = fap_unit(key[0], head.fapu)
            for t in table.transforms:
                node = "pivot" if t.part is None else t.part
                if t.kind != "rotation" or node not in movers:
                    warnings.add(f"FAP {key[0]}: a {t.kind} of {t.part or 'the head'} cannot be a glTF node "
                                 "animation and is left out")
                    continue
                mats[node] = t.affine(values[k], unit)[0] @ mats[node]
        for node, m in mats.items():
            rotations[node][i] = Rotation.from_matrix(m).as_quat()
    for phrase, count in sorted(decode.clamped.items()):
        warnings.add(f"{phrase} in {count} of {held.n_frames} frames (--no-limits plays the values as given)")
    pivot = head.fp_position("7.1") if "7.1" in head.feature_points else np.zeros(3)
    # Drop channels that never move.
    weights = {k: v for k, v in weights.items() if np.any(v)}
    rotations = {k: q for k, q in rotations.items() if np.abs(q[:, :3]).max() > 0}
    return GlbAnimation(times, weights, rotations, pivot, name=stream.name), sorted(warnings)


def render_preview_frames(head: Head, stream, size: int = 400, max_fps: float = 15.0, yaw_deg: float = 15.0,
                          limits: bool = True):
    """Offscreen renders of a stream: (frames list of (H, W, 3) uint8, frame duration s)."""
    from mpeg4.camera import Camera
    from mpeg4.preview import head_meshes
    from mpeg4.render import render

    from .play import Player

    player = Player(head, limits=limits)
    held = stream.held()
    step = max(1, int(round(stream.fps / max_fps)))
    _, fps = head.fp_array()
    cam = Camera.fit(fps, int(size * 0.8), size, yaw_deg=yaw_deg, pitch_deg=5, margin=0.1, focal_px=2.5 * size)
    frames = []
    for i in range(0, held.n_frames, step):
        parts = player.part_vertices(player.vertices(held.frame_values(i)))
        frames.append(render(head_meshes(head, parts), cam))
    return frames, step / stream.fps


def write_gif(frames, duration: float, path) -> str:
    """An animated GIF (atomic write)."""
    import io

    from PIL import Image

    from mpeg4.io.atomic import atomic_write

    images = [Image.fromarray(f).convert("P", palette=Image.Palette.ADAPTIVE, colors=128) for f in frames]
    buf = io.BytesIO()
    images[0].save(buf, format="GIF", save_all=True, append_images=images[1:], duration=int(round(duration * 1000)),
                   loop=0)
    with atomic_write(path, "wb") as f:
        f.write(buf.getvalue())
    return os.fspath(path)


def write_video(frames, fps: float, path, audio=None) -> str:
    """An H.264 MP4 of ``frames`` at ``fps``, with ``audio`` (a WAV path) muxed in when
    given; encoded by the ffmpeg that the imageio-ffmpeg package ships (atomic write)."""
    import subprocess
    import tempfile

    import imageio_ffmpeg

    h, w = frames[0].shape[:2]
    h2, w2 = h - h % 2, w - w % 2  # yuv420p wants even sizes
    folder = os.path.dirname(os.path.abspath(os.fspath(path)))
    os.makedirs(folder, exist_ok=True)
    fd, tmp = tempfile.mkstemp(suffix=".mp4", dir=folder)
    os.close(fd)
    cmd = [imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-loglevel", "error", "-f", "rawvideo", "-pix_fmt", "rgb24",
           "-s", f"{w2}x{h2}", "-r", f"{fps:g}", "-i", "-"]
    if audio is not None:
        cmd += ["-i", os.fspath(audio), "-c:a", "aac", "-shortest"]
    cmd += ["-c:v", "libx264", "-pix_fmt", "yuv420p", "-movflags", "+faststart", tmp]
    try:
        data = b"".join(np.ascontiguousarray(f[:h2, :w2, :3]).tobytes() for f in frames)
        run = subprocess.run(cmd, input=data, capture_output=True)
        if run.returncode != 0:
            raise RuntimeError(f"ffmpeg failed: {run.stderr.decode(errors='replace')[-300:]}")
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return os.fspath(path)


def write_animation(head: Head, stream, out_dir, preview: bool = True, audio=None, max_fps: float = 15.0,
                    progress: Callable[[str], None] | None = None, limits: bool = True) -> dict[str, Path]:
    """Write ``animation.glb`` for a stream on a head, and with ``preview`` a GIF (and an MP4
    with ``audio`` muxed in when an audio file is given) into ``out_dir``; ``limits=False``
    plays the values without the limits a face has."""
    from mpeg4.io import write_glb

    say_ = progress or (lambda msg: None)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    head = covering_head(head, stream, limits=limits)  # morph weights within [0, 1]
    anim, warnings = stream_animation(head, stream, limits=limits)
    for w in warnings:
        say_(f"warning: {w}")
    paths = {"animation": out / "animation.glb"}
    write_glb(head, paths["animation"], animation=anim)
    if preview:
        say_("rendering the preview" + (" (GIF, and MP4 with the sound)" if audio is not None else ""))
        frames, duration = render_preview_frames(head, stream, max_fps=max_fps, limits=limits)
        paths["preview"] = out / "preview.gif"
        write_gif(frames, duration, paths["preview"])
        if audio is not None:
            paths["video"] = out / "preview.mp4"
            write_video(frames, 1.0 / duration, paths["video"], audio=audio)
    return paths


def play_stream(head_path, stream_path, out_dir, preview: bool = True, lenient: bool = False,
                progress: Callable[[str], None] | None = None, limits: bool = True) -> dict[str, Path]:
    """``fmc play``: the animated GLB (and a preview GIF) of a FAP stream on a head."""
    from mpeg4.io import read_fap

    from .heads import animated_head

    say = progress or (lambda msg: None)
    t0 = time.perf_counter()
    head = animated_head(head_path)
    stream = read_fap(stream_path, lenient=lenient)
    say(f"{stream.n_frames} frames at {stream.fps:g} fps")
    paths = write_animation(head, stream, out_dir, preview=preview, progress=say, limits=limits)
    say(f"done in {time.perf_counter() - t0:.1f} s")
    return paths


def say(head_path, text: str, out_dir, voice: str = "en", preview: bool = True, eyes: bool = True,
        seed: int = 0, expression: str | int | None = None, intensity: float = 0.7,
        progress: Callable[[str], None] | None = None) -> dict[str, Path]:
    """``fmc say``: speak ``text`` on a head — speech.wav, speech.fap, animation.glb, preview.gif.

    Phonemes and audio come from espeak-ng (:mod:`fmc.speech`), visemes are coarticulated
    by dominance functions (:mod:`fmc.coarticulation`) and played through the head's FATs;
    with ``eyes`` the eyes blink and look around (:mod:`fmc.eyes`, seeded by ``seed``),
    looking at the listener while speaking; with ``expression`` (a name or number) the
    face holds that expression at ``intensity`` while it speaks, and bilabials still close
    the lips (:func:`fmc.coarticulation.close_bilabials`).
    """
    from mpeg4.io import write_fap

    from .heads import animated_head

    from .coarticulation import speech_stream
    from .speech import synthesize, write_wav

    say_ = progress or (lambda msg: None)
    t0 = time.perf_counter()
    head = animated_head(head_path)
    if head.fat is None or not len(head.fat):
        raise InputError("the head has no Facial Animation Tables to speak with",
                         where=os.fspath(head_path), fix="author them first: fmc author HEAD -o HEAD_WITH_FAT.glb")
    utterance = synthesize(text, voice=voice)
    say_(f"{len(utterance.phonemes)} phonemes, {utterance.duration:.2f} s of speech")
    stream = speech_stream(utterance.phonemes, utterance.duration)
    if expression is not None:
        from .actions import Action, _lookup, blend
        from mpeg4.catalogue import EXPRESSIONS

        e = _lookup(EXPRESSIONS, expression, "expression", "--expression")
        act = Action({(2, e): 63.0}, 0.0, (stream.n_frames - 1) / stream.fps, intensity=intensity, attack=0.3,
                     release=0.3)
        level = blend([act], stream.frame_numbers / stream.fps)[(2, e)]
        stream.expression[:] = np.c_[np.full(stream.n_frames, e), level, np.zeros((stream.n_frames, 4))]
    if eyes:
        from .eyes import eyes_alive

        voiced = [p for p in utterance.phonemes if p.viseme]
        speaking = [(voiced[0].start, voiced[-1].end)] if voiced else []
        span = (stream.n_frames - 1) / stream.fps
        for k, v in eyes_alive(span, stream.fps, seed=seed, speaking=speaking).items():
            stream.values[:, k - 1] = v[:stream.n_frames]
    if head.fat is not None and len(head.fat):
        from .coarticulation import close_bilabials
        from .play import Player

        close_bilabials(Player(head, limits=False), stream, utterance.phonemes)  # it closes, never crosses
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"audio": out / "speech.wav", "stream": out / "speech.fap"}
    write_wav(utterance, paths["audio"])
    write_fap(stream, paths["stream"])
    paths.update(write_animation(head, stream, out, preview=preview, audio=paths["audio"], max_fps=25.0,
                                 progress=say_))
    say_(f"done in {time.perf_counter() - t0:.1f} s")
    return paths


def animate_timeline(head_path, timeline_path, out_dir, preview: bool = True,
                     progress: Callable[[str], None] | None = None) -> dict[str, Path]:
    """``fmc animate``: blend a timeline of actions (:mod:`fmc.actions`) and play it on a
    head — timeline.fap, animation.glb, preview.gif."""
    from mpeg4.io import write_fap

    from .heads import animated_head

    from .actions import read_timeline

    say_ = progress or (lambda msg: None)
    t0 = time.perf_counter()
    timeline = read_timeline(timeline_path)
    head = animated_head(head_path)
    stream = timeline.stream()
    say_(f"{len(timeline.actions)} actions, {stream.n_frames} frames at {stream.fps:g} fps")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"stream": out / "timeline.fap"}
    write_fap(stream, paths["stream"])
    paths.update(write_animation(head, stream, out, preview=preview, progress=say_))
    say_(f"done in {time.perf_counter() - t0:.1f} s")
    return paths
