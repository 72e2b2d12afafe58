"""Probes: bad input, kills and hostile requests, kept as tests.

Each probe feeds the tools something a careless or hostile user could: files nested
deeper than any parser's stack, repeated keys, numbers beyond a double or a frame counter,
truncated and oversized GLBs, random bytes shaped like the formats (hypothesis), writes
interrupted between two steps. What must come back is what the README promises: one line
naming the file, the place and the fix (an :class:`~mpeg4.errors.InputError`, exit status 2
at the command line), nothing half-written, nothing lost.

Probes of the annotation server (two processes saving at once, idle connections, the
token, a swapped photo) and of a build killed between two steps are beside the modules'
tests: ``tests/recon/test_annotate_probes.py``, ``tests/recon/test_publish.py``; the memory
probes (huge photos, a 3.1-million-triangle mesh) in ``tests/recon/test_build.py`` and
``tests/recon/test_mark.py``.
"""

import json
import os
import re
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mpeg4.errors import InputError
from mpeg4.generic_head import load_generic_head
from mpeg4.head import Head, Part, SparseDisplacement
from mpeg4.io import load_head, write_glb, write_obj
from mpeg4.io.fap import MAX_FAP_VALUE, FapStream, parse_fap, write_fap
from mpeg4.io.fdp_json import FdpFile, parse_fdp, read_fdp_json, write_fdp_json
from mpeg4.io.strict_json import MAX_DEPTH, loads

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE_FDP = ROOT / "data" / "example" / "example.fdp.json"
MASK_3 = "0 0 1" + " 0" * 65  # FAP 3 (open_jaw) only
FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _cli(*argv, cwd=None):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", *map(str, argv)], capture_output=True, text=True, cwd=cwd or ROOT,
                          env=env, timeout=300)


def _one_line(run, needle: str) -> None:
    """Exit status 2 and one error line holding ``needle`` (progress lines may come before it)."""
    assert run.returncode == 2, (run.returncode, run.stderr[-2000:])
    errors = [line for line in run.stderr.splitlines() if re.match(r"(recon|fmc): error: ", line) or "Error" in line]
    assert "Traceback" not in run.stderr and len(errors) == 1, run.stderr[-2000:]
    assert needle in errors[0], run.stderr


def _small_head() -> Head:
    v = np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.1]], float)
    return Head({"skin": Part("skin", v, [[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]])})


# --- JSON: nesting, repeated keys, numbers -------------------------------------------

def test_json_nested_deeper_than_the_limit_is_refused_in_one_line(tmp_path):
    deep = tmp_path / "deep.fdp.json"
    deep.write_text('{"format": "mpeg4-fdp", "version": 1, "metadata": ' + "[" * 100000 + "]" * 100000 + "}")
    with pytest.raises(InputError, match=r"deep.fdp.json: JSON nested 100001 levels deep, more than the 64"):
        read_fdp_json(deep)
    # At the limit it parses; one more level is refused.
    assert json.dumps(loads("[" * MAX_DEPTH + "]" * MAX_DEPTH, "x")) == "[" * MAX_DEPTH + "]" * MAX_DEPTH
    with pytest.raises(InputError, match="nested 65 levels deep"):
        loads("[" * (MAX_DEPTH + 1) + "]" * (MAX_DEPTH + 1), "x")


def test_deep_json_gives_one_line_at_the_command_line(tmp_path):
    deep = tmp_path / "deep.fdp.json"
    deep.write_text("[" * 200000 + "]" * 200000)
    _one_line(_cli("recon", "build", "--fdp", deep, "-o", tmp_path / "out"), "JSON nested 200000 levels deep")
    timeline = tmp_path / "t.json"
    timeline.write_text('{"actions": ' + "[" * 200000 + "]" * 200000 + "}")
    _one_line(_cli("fmc", "animate", ROOT / "data" / "generic_head" / "generic_head.glb", timeline, "-o", tmp_path / "a"),
              "t.json: JSON nested 200001 levels deep")
    # fmc info on an OBJ whose fdp.json beside it is nested; on a nested .gltf.
    (tmp_path / "h.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "h.fdp.json").write_text("[" * 200000 + "]" * 200000)
    _one_line(_cli("fmc", "info", tmp_path / "h.obj"), "h.fdp.json: JSON nested 200000 levels deep")
    (tmp_path / "deep.gltf").write_text('{"asset": {"version": "2.0"}, "extras": ' + "[" * 200000 + "]" * 200000 + "}")
    _one_line(_cli("fmc", "info", tmp_path / "deep.gltf"), "deep.gltf")
    # recon annotate with a nested annotation file: refused before it serves anything.
    _one_line(_cli("recon", "annotate", ROOT / "data" / "example" / "front.jpg", ROOT / "data" / "example" / "side.jpg",
                   "--fdp", deep, "--no-browser", "--no-detect"), "deep.fdp.json: JSON nested 200000 levels deep")


def test_a_key_given_twice_is_refused(tmp_path):
    text = EXAMPLE_FDP.read_text()
    twice = tmp_path / "twice.fdp.json"
    twice.write_text(text.replace('"version": 1,', '"version": 1, "version": 1,', 1))
    with pytest.raises(InputError, match=r"twice.fdp.json: the key 'version' appears twice in one object"):
        read_fdp_json(twice)
    manifest = tmp_path / "m.jsonl"
    manifest.write_text('{"id": "a", "id": "b", "front": "f.jpg", "side": "s.jpg"}\n')
    from recon.batch.manifest import read_manifest

    with pytest.raises(InputError, match=r"m.jsonl, line 1: the key 'id' appears twice"):
        read_manifest(manifest)


@pytest.mark.parametrize("token, why", [("1e400", "too large for a double"), ("NaN", "not a finite number"),
                                        ("-Infinity", "not a finite number"),
                                        ("123456789012345678901234567890", "whole number beyond")])
def test_numbers_json_cannot_hold_are_refused_with_their_line(tmp_path, token, why):
    path = tmp_path / "n.fdp.json"
    path.write_text('{"format": "mpeg4-fdp",\n "version": 1,\n "points3d": {"3.5": [0, ' + token + ', 0]}}')
    with pytest.raises(InputError, match=rf"n.fdp.json, line 3, column 26: .* {why}"):
        read_fdp_json(path)


_json_values = st.recursive(st.none() | st.booleans() | st.integers(-2 ** 60, 2 ** 60) | st.floats() | st.text(max_size=8),
                            lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner,
                                                                                        max_size=4), max_leaves=30)


@FUZZ
@given(st.one_of(st.binary(max_size=300), st.text(max_size=300)))
def test_fuzzed_bytes_are_an_fdp_file_or_a_one_line_error(tmp_path, data):
    path = tmp_path / "f.fdp.json"
    path.write_bytes(data if isinstance(data, bytes) else data.encode("utf-8", "surrogatepass"))
    try:
        read_fdp_json(path)
    except InputError as e:
        assert "\n" not in str(e) and str(e).startswith(str(path))


@FUZZ
@given(st.sampled_from(["views", "points3d", "bindings", "texcoords", "fapu", "frame", "parts", "metadata",
                        "version", "units"]), _json_values)
def test_fuzzed_fields_of_a_real_file_are_read_or_refused_in_one_line(key, value):
    data = json.loads(EXAMPLE_FDP.read_text())
    data[key] = value
    try:
        parse_fdp(data, where="fuzz.fdp.json")
    except InputError as e:
        assert "\n" not in str(e) and str(e).startswith("fuzz.fdp.json")


def test_a_key_with_a_line_break_is_named_on_one_line():
    """The fuzzing found it: a part named "a\nb" put its line break in the message."""
    data = json.loads(EXAMPLE_FDP.read_text())
    data["parts"] = {"a\nb": 1}
    with pytest.raises(InputError) as e:
        parse_fdp(data, where="key.fdp.json")
    assert "\n" not in str(e.value) and 'parts["a\\nb"]' in str(e.value)


# --- .fap streams ---------------------------------------------------------------------

@pytest.mark.parametrize("text, message", [
    (f"2.1 x 25 1\n{MASK_3}\n99999999999999999999 5\n", r"a.fap, line 3: frame number 99999999999999999999 is beyond"),
    (f"2.1 x 25 99999999999999999999\n{MASK_3}\n0 5\n", r"a.fap, line 1: frame count 99999999999999999999 is not"),
    (f"2.1 x 1e-300 1\n{MASK_3}\n0 5\n", r"a.fap, line 1: frame rate 1e-300 is outside 0.01..10000"),
    (f"2.1 x 1e300 1\n{MASK_3}\n0 5\n", r"a.fap, line 1: frame rate 1e300 is outside"),
    (f"2.1 x 25 1\n{MASK_3}\n0 1e300\n", r"a.fap, line 3: frame 0: FAP 3 \(open_jaw\) is 1e300, beyond"),
    (f"2.1 x 25 1\n{MASK_3}\n0 1e400\n", r"a.fap, line 3: value '1e400' is not a finite number"),
])
def test_huge_numbers_in_a_fap_file_are_refused_with_the_line(text, message):
    with pytest.raises(InputError, match=message):
        parse_fap(text, where="a.fap")


def test_fmc_play_refuses_a_fap_value_of_1e300_in_one_line_and_writes_nothing(tmp_path):
    from mpeg4.io import save_head

    head = tmp_path / "fat.glb"  # a head with animation tables: before, it played 1e300 into NaN weights
    save_head(load_generic_head(with_fat=True), head)
    stream = tmp_path / "big.fap"
    stream.write_text(f"2.1 big 25 2\n{MASK_3}\n0 100\n{MASK_3}\n1 1e300\n")
    run = _cli("fmc", "play", head, stream, "-o", tmp_path / "out", "--no-preview")
    _one_line(run, "big.fap, line 5: frame 1: FAP 3 (open_jaw) is 1e300")
    assert not (tmp_path / "out" / "animation.glb").exists()


def test_a_stream_made_in_code_with_a_huge_value_names_its_frame_and_fap():
    from fmc.animate import stream_animation

    values = np.full((3, 68), np.nan)
    values[:, 2] = [0, 10, 1e300]
    with pytest.raises(InputError, match=r"frame 2: FAP 3 \(open_jaw\) is 1e\+300, beyond"):
        stream_animation(load_generic_head(with_fat=True), FapStream.from_values(values))
    with pytest.raises(InputError, match="frame rate 1e-300 is outside"):
        FapStream.from_values(values, fps=1e-300)


_fap_token = st.sampled_from(["0", "1", "-1", "25", "2.1", "1e300", "1e400", "nan", "inf", "99999999999999999999",
                              "x", "#", "0.5", "63", "14", "-0", "1e-300"])
_fap_line = st.lists(_fap_token, min_size=0, max_size=70).map(" ".join)


@FUZZ
@given(st.lists(_fap_line, max_size=8), st.booleans())
def test_fuzzed_fap_text_is_a_stream_or_a_one_line_error(lines, lenient):
    text = "\n".join(lines)
    try:
        s = parse_fap(text, where="fuzz.fap", lenient=lenient)
    except InputError as e:
        assert "\n" not in str(e) and str(e).startswith("fuzz.fap")
    else:
        assert np.isfinite(s.frame_numbers).all() and 0.01 <= s.fps <= 10000
        assert not (np.abs(np.nan_to_num(s.values)) > MAX_FAP_VALUE).any()


@FUZZ
@given(st.lists(st.integers(0, 67), min_size=1, max_size=3), st.lists(st.floats(-2e6, 2e6), min_size=1, max_size=3))
def test_fuzzed_valid_streams_survive_a_round_trip(tmp_path, faps, vals):
    values = np.full((len(vals), 68), np.nan)
    for i, v in enumerate(vals):
        values[i, 2 + faps[i % len(faps)] % 66] = v
    stream = FapStream.from_values(values)
    path = tmp_path / "s.fap"
    try:
        write_fap(stream, path)
    except InputError as e:
        assert "beyond the 1e+06" in str(e) and np.abs(vals).max() > MAX_FAP_VALUE
        return
    back = parse_fap(path.read_text(), where="s.fap")
    np.testing.assert_allclose(np.nan_to_num(back.values), np.nan_to_num(values), rtol=1e-12)


# --- everything written is finite -----------------------------------------------------

def test_writers_refuse_nan_and_infinity_naming_what_and_write_nothing(tmp_path):
    head = _small_head()
    head.morph_targets = {"smile": {"skin": SparseDisplacement(np.array([1, 2]), np.array([[0, 0, 1e-3], [0, 0, 1e300]]))}}
    with pytest.raises(InputError, match=r"h.glb: morph target 'smile' of part 'skin': displacement 1 is not a finite "
                                         r"number \(NaN, or beyond the float32 range of glTF\)"):
        write_glb(head, tmp_path / "h.glb")
    head.morph_targets = {}
    head.parts["skin"].uv = np.array([[0, 0], [1, 0], [np.nan, 1], [1, 1]], float)
    with pytest.raises(InputError, match=r"h.glb: part 'skin': the texture coordinates of vertex 2 is not a finite"):
        write_glb(head, tmp_path / "h.glb")
    with pytest.raises(InputError, match=r"h.obj: part 'skin': texture coordinate of vertex 2 is not a finite number"):
        write_obj(head, tmp_path / "h.obj")
    fdp = FdpFile(points3d={"3.5": np.array([0.0, np.inf, 0.0])})
    with pytest.raises(InputError, match=r'p.fdp.json, points3d\["3.5"\]\[1\]: not a finite number'):
        write_fdp_json(tmp_path / "p.fdp.json", fdp)
    values = np.full((2, 68), np.nan)
    values[1, 5] = np.inf
    with pytest.raises(InputError, match=r"s.fap: frame 1: FAP 6 \(stretch_l_cornerlip\) is inf"):
        write_fap(FapStream.from_values(values), tmp_path / "s.fap")
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_an_animation_that_overflows_float32_is_refused_naming_the_frame(tmp_path):
    from mpeg4.io.gltf import GlbAnimation

    head = _small_head()
    head.morph_targets = {"up": {"skin": SparseDisplacement(np.array([1]), np.array([[0, 0.01, 0]]))}}
    anim = GlbAnimation(np.array([0.0, 0.04, 0.08]), weights={"up": np.array([0.0, 1.0, 1e300])})
    with pytest.raises(InputError, match=r"a.glb: the animation's weight of morph target 'up' at frame 2 is not a finite"):
        write_glb(head, tmp_path / "a.glb", animation=anim)
    assert not (tmp_path / "a.glb").exists()


def test_a_nan_vertex_names_the_file_the_part_the_vertex_and_the_fix(tmp_path):
    obj = tmp_path / "bad.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n")
    with pytest.raises(InputError, match=r"bad.obj, part '.*': vertex 2 \(of 1 such\) has a NaN or infinite coordinate "
                                         r"\(fix: export the mesh again"):
        load_head(obj)
    _one_line(_cli("fmc", "info", obj), "bad.obj, part")


# --- GLBs: truncated, oversized, hostile ----------------------------------------------

@pytest.fixture(scope="module")
def small_glb(tmp_path_factory):
    path = tmp_path_factory.mktemp("glb") / "small.glb"
    head = load_generic_head()
    head.morph_targets = {k: head.morph_targets[k] for k in list(head.morph_targets)[:2]}
    write_glb(head, path)
    return path.read_bytes()


def _read_or_refuse(path: Path) -> None:
    try:
        load_head(path)
    except InputError as e:
        assert "\n" not in str(e) and str(e).startswith(str(path)), str(e)


def test_truncated_glbs_are_refused_in_one_line(small_glb, tmp_path):
    cuts = sorted({0, 4, 12, 19, 20, 27, 28} | set(np.linspace(30, len(small_glb) - 1, 40).astype(int).tolist()))
    for cut in cuts:
        path = tmp_path / f"cut{cut}.glb"
        path.write_bytes(small_glb[:cut])
        _read_or_refuse(path)


def test_oversized_glb_claims_are_refused_without_reading_them(small_glb, tmp_path):
    json_len = struct.unpack("<I", small_glb[12:16])[0]
    doc = json.loads(small_glb[20:20 + json_len])
    cases = {
        "length": small_glb[:8] + struct.pack("<I", 2 ** 32 - 1) + small_glb[12:],
        "json_chunk": small_glb[:12] + struct.pack("<I", 2 ** 32 - 4) + small_glb[16:],
        "padded": small_glb + b"\0" * (1 << 20),
    }
    rest = small_glb[20 + json_len:]
    for name, change in (("count", lambda d: d["accessors"][0].update(count=2 ** 31)),
                         ("view", lambda d: d["bufferViews"][0].update(byteLength=2 ** 40)),
                         ("buffer", lambda d: d["buffers"][0].update(byteLength=2 ** 40)),
                         ("targets", lambda d: d["accessors"][0].update(bufferView=10 ** 6))):
        big = json.loads(json.dumps(doc))
        change(big)
        text = json.dumps(big).encode()
        text += b" " * (-len(text) % 4)
        cases[name] = (small_glb[:8] + struct.pack("<I", 20 + len(text) + len(rest)) + struct.pack("<I", len(text))
                       + b"JSON" + text + rest)
    for name, data in cases.items():
        path = tmp_path / f"{name}.glb"
        path.write_bytes(data)
        _read_or_refuse(path)


def test_a_node_hierarchy_with_a_cycle_or_thousands_deep_is_refused_or_read(tmp_path):
    import trimesh

    scene = trimesh.Scene(trimesh.creation.box((0.1, 0.2, 0.3)))
    path = tmp_path / "box.glb"
    scene.export(path)
    data = path.read_bytes()
    json_len = struct.unpack("<I", data[12:16])[0]
    doc = json.loads(data[20:20 + json_len])
    rest = data[20 + json_len:]

    def glb(d, name):
        text = json.dumps(d).encode()
        text += b" " * (-len(text) % 4)
        p = tmp_path / name
        p.write_bytes(b"glTF" + struct.pack("<II", 2, 20 + len(text) + len(rest)) + struct.pack("<I", len(text))
                      + b"JSON" + text + rest)
        return p

    cyclic = json.loads(json.dumps(doc))
    cyclic["nodes"].append({"children": [len(cyclic["nodes"])]})
    cyclic["scenes"][0]["nodes"].append(len(cyclic["nodes"]) - 1)
    with pytest.raises(InputError, match="is reached twice in the scene's hierarchy"):
        load_head(glb(cyclic, "cyclic.glb"))
    deep = json.loads(json.dumps(doc))
    first = len(deep["nodes"])
    deep["nodes"] += [{"children": [first + k + 1]} for k in range(5000)] + [{"mesh": 0}]
    deep["scenes"][0]["nodes"] = [first]
    head = load_head(glb(deep, "deep.glb"))  # 5001 levels: read with a stack of its own
    assert len(head.parts) == 1 and len(next(iter(head.parts.values())).triangles) == 12
