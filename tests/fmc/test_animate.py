"""Animated GLB: valid, and a viewer following glTF's rules sees what the decoder computes."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from fmc.animate import play_stream, stream_animation
from fmc.play import Player
from mpeg4.io import FapStream, read_glb, write_fap, write_glb
from mpeg4.io.gltf import posed_parts, read_glb_animation


@pytest.fixture(scope="module")
def head(authored_head):
    return authored_head


def _stream():
    n = 12
    values = np.full((n, 68), np.nan)
    t = np.linspace(0, 1, n)
    values[:, 2] = 400 * np.sin(np.pi * t)  # open_jaw
    values[:, 11] = 150 * t  # raise_l_cornerlip
    values[:, 22] = 20000 * t  # yaw_l_eyeball
    values[:, 48] = -15000 * np.sin(np.pi * t)  # head_yaw
    vis = np.full((n, 4), np.nan)
    vis[:, :] = [10, 1, 40, 0]
    return FapStream.from_values(values, fps=25, viseme=vis, name="test")


def _gltf_view(back, anim, i):
    """Vertices at frame i the way a glTF viewer computes them."""
    parts = {}
    for name, p in back.parts.items():
        v = p.vertices.copy()
        for tname, target in {**back.morph_targets, **_fat_targets(back)}.items():
            w = anim.weights.get(tname)
            if w is not None and name in target:
                v[target[name].indices] += w[i] * target[name].vectors
        if name in anim.rotations:
            r = Rotation.from_quat(anim.rotations[name][i]).as_matrix()
            v = (v - p.centre) @ r.T + p.centre
        parts[name] = v
    if "pivot" in anim.rotations:
        r = Rotation.from_quat(anim.rotations["pivot"][i]).as_matrix()
        parts = {n: (v - anim.pivot) @ r.T + anim.pivot for n, v in parts.items()}
    return parts


def _fat_targets(h):
    from mpeg4.fat import fat_to_morph_targets

    return fat_to_morph_targets(h.fat, h.fapu)[0]


def test_animation_round_trip_matches_the_decoder(head, tmp_path, validate_gltf):
    stream = _stream()
    anim, warnings = stream_animation(head, stream)
    assert not warnings
    path = write_glb(head, tmp_path / "a.glb", animation=anim)
    report = validate_gltf(path)
    assert report["issues"]["numErrors"] == 0, report["issues"]["messages"][:3]
    back = read_glb(path)
    got = read_glb_animation(path)
    np.testing.assert_allclose(got.times, np.arange(12) / 25, atol=1e-6)
    assert set(back.parts) == set(head.parts) and np.allclose(got.pivot, head.fp_position("7.1"))
    player = Player(head)
    held = stream.held()
    for i in (0, 5, 11):
        want = player.part_vertices(player.vertices(held.frame_values(i)))
        seen = posed_parts(path, i)  # morphs, then the neck's skinning, as glTF defines them
        assert max(np.abs(seen[n] - want[n]).max() for n in want) < 2e-5  # float32 storage


def test_fmc_play_writes_glb_and_gif(head, tmp_path):
    from PIL import Image

    write_glb(head, tmp_path / "h.glb")
    write_fap(_stream(), tmp_path / "s.fap")
    paths = play_stream(tmp_path / "h.glb", tmp_path / "s.fap", tmp_path / "out")
    gif = Image.open(paths["preview"])
    assert gif.n_frames >= 6
    assert read_glb_animation(paths["animation"]).weights


def test_video_with_audio(tmp_path):
    import subprocess
    import wave

    import imageio_ffmpeg

    from fmc.animate import write_video

    with wave.open(str(tmp_path / "a.wav"), "wb") as w:
        w.setnchannels(1)
        w.setsampwidth(2)
        w.setframerate(16000)
        w.writeframes((3000 * np.sin(np.arange(16000) / 10)).astype("<i2").tobytes())
    frames = [np.full((61, 81, 3), k * 20, np.uint8) for k in range(10)]
    path = write_video(frames, 10.0, tmp_path / "v.mp4", audio=tmp_path / "a.wav")
    info = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-i", path], capture_output=True,
                          text=True).stderr
    assert "Video: h264" in info and "Audio: aac" in info and "80x60" in info


def test_weights_stay_within_0_and_1_so_every_viewer_plays_the_same(head, tmp_path, validate_gltf):
    """Values past the tables' ±512 borders (a Xface jaw of 713, a lip of −866) would need
    weights above 1, which Blender clamps and three.js does not: the written GLB's tables
    reach the stream's values instead, and a viewer that clamps sees what the decoder does."""
    from fmc.animate import covering_head

    n = 10
    values = np.full((n, 68), np.nan)
    t = np.linspace(0, 1, n)
    values[:, 2] = 900 * t  # open_jaw beyond 512
    values[:, 11] = -800 * t  # raise_l_cornerlip, the other way beyond −512
    values[:, 18] = 700 * t  # close_t_l_eyelid
    stream = FapStream.from_values(values, fps=25)
    plain, _ = stream_animation(head, stream)
    assert max(w.max() for w in plain.weights.values()) > 1.5  # the problem
    covered = covering_head(head, stream)
    anim, _ = stream_animation(covered, stream)
    assert all(0.0 <= w.min() and w.max() <= 1.0 + 1e-9 for w in anim.weights.values())
    path = write_glb(covered, tmp_path / "a.glb", animation=anim)
    assert validate_gltf(path)["issues"]["numErrors"] == 0
    back, got = read_glb(path), read_glb_animation(path)
    got.weights = {k: np.clip(w, 0.0, 1.0) for k, w in got.weights.items()}  # as Blender plays them
    player = Player(head)
    held = stream.held()
    for i in (3, 6, 9):
        want = player.part_vertices(player.vertices(held.frame_values(i)))
        seen = _gltf_view(back, got, i)
        assert max(np.abs(seen[n] - want[n]).max() for n in want) < 1e-5  # float32 storage: 0.01 mm


def test_fmc_play_takes_the_generic_head_by_name_or_by_its_glb(tmp_path):
    """The generic head's GLB keeps its tables beside it (generic_head_fat.npz): play finds
    them, and 'generic' names it; a limit that acts is said."""
    from typer.testing import CliRunner

    from fmc.cli import app
    from mpeg4.generic_head import generic_head_path

    values = np.full((6, 68), np.nan)
    values[:, 18], values[:, 20] = 1080.0, 600.0  # lids asked to pass each other
    write_fap(FapStream.from_values(values, fps=25), tmp_path / "s.fap")
    for head in ("generic", str(generic_head_path())):
        out = CliRunner().invoke(app, ["play", head, str(tmp_path / "s.fap"), "-o", str(tmp_path / "out"),
                                       "--no-preview"])
        assert out.exit_code == 0, out.output
        assert "stopped where they meet in 6 of 6 frames" in out.output
        assert (tmp_path / "out" / "animation.glb").exists()
