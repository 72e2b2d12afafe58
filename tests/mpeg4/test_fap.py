""".fap streams: the reference's example, files in the wild, round trips, line-numbered errors."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mpeg4 import InputError
from mpeg4.io import FapStream, describe_fap, format_fap, parse_fap, read_fap, write_fap

MASK_3_49 = " ".join("1" if k in (3, 49) else "0" for k in range(1, 69))
EXAMPLE = f"2.1 demo 25 2\n{MASK_3_49}\n0 0 0\n{MASK_3_49}\n1 300 5000\n"


def test_reference_example():
    s = parse_fap(EXAMPLE)
    assert (s.version, s.name, s.fps, s.n_frames) == ("2.1", "demo", 25.0, 2)
    assert s.values[1, 2] == 300 and s.values[1, 48] == 5000
    assert np.isnan(s.values[1, 3])
    assert s.frame_values(1) == {3: 300.0, 49: 5000.0}
    assert s.duration == pytest.approx(2 / 25)


def test_files_in_the_wild():
    zeros = " ".join(["0"] * 68)
    vis = "\t".join("1" if k in (1, 2, 19) else "0" for k in range(1, 69))
    text = ("# exported by some tool\r\n"
            "2.2 C:\\anim\\take 3.fap 30.0 5\r\n"   # a path with a space as the name, float fps, wrong count
            "# a comment between frames\r\n"
            f"{zeros}\r\n1\r\n"                      # frames from 1, an empty frame
            "\r\n"
            f"{vis}\r\n2\t4 7 40 0\t1 63 6 10 0 0\t-12.5\r\n"
            "# trailing comment\r\n")
    with pytest.raises(InputError, match=r"wild.fap, line 2: the header says 5 frames but the file holds 2"):
        parse_fap(text, where="wild.fap")
    s = parse_fap(text, where="wild.fap", lenient=True)
    assert s.version == "2.2" and s.name == "C:\\anim\\take 3.fap" and s.fps == 30.0
    assert s.n_frames == 2 and s.declared_frames == 5
    assert s.frame_numbers.tolist() == [1, 2]
    assert not s.mask[0].any()
    np.testing.assert_array_equal(s.viseme[1], [4, 7, 40, 0])
    np.testing.assert_array_equal(s.expression[1], [1, 63, 6, 10, 0, 0])
    assert s.values[1, 18] == -12.5
    fv = s.frame_values(1)
    assert fv[(1, 4)] == 40 and fv[(1, 7)] == 23 and fv[(2, 1)] == 63 and fv[(2, 6)] == 10 and fv[19] == -12.5
    assert "frames that set no FAP: 1" in describe_fap(s)
    assert "the header says 5" in describe_fap(s)


def test_held_values_carry_forward():
    vals = np.full((4, 68), np.nan)
    vals[1, 2] = 100
    vals[3, 2] = 50
    held = FapStream.from_values(vals).held()
    assert np.isnan(held.values[0, 2]) and held.values[1:, 2].tolist() == [100, 100, 50]
    assert 3 not in held.frame_values(0) and held.frame_values(2)[3] == 100


@st.composite
def streams(draw):
    n = draw(st.integers(0, 6))
    rng = np.random.default_rng(draw(st.integers(0, 2 ** 32 - 1)))
    mask = rng.random((n, 68)) < draw(st.floats(0, 1))
    values = np.where(mask, rng.integers(-2000, 2000, (n, 68)) + rng.choice([0, 0.25, 0.5], (n, 68)), np.nan)
    values[:, :2] = np.nan
    vis = np.where(mask[:, :1], np.c_[rng.integers(0, 15, (n, 2)), rng.integers(0, 64, n), rng.integers(0, 2, n)],
                   np.nan)
    exp = np.where(mask[:, 1:2], np.c_[rng.integers(0, 7, n), rng.integers(0, 64, n), rng.integers(0, 7, n),
                                       rng.integers(0, 64, n), rng.integers(0, 2, (n, 2))], np.nan)
    frames = np.cumsum(rng.integers(1, 3, n)) - 1 + draw(st.integers(0, 1))
    fps = draw(st.sampled_from([25.0, 29.97, 30.0, 12.5]))
    return FapStream(fps, frames, values, vis, exp, name="take", version=draw(st.sampled_from(["2.0", "2.1", "2.2"])))


@settings(max_examples=60, deadline=None)
@given(streams())
def test_round_trip(s):
    back = parse_fap(format_fap(s))
    assert (back.fps, back.name, back.version, back.declared_frames) == (s.fps, s.name, s.version, None)
    np.testing.assert_array_equal(back.frame_numbers, s.frame_numbers)
    np.testing.assert_array_equal(back.values, s.values)  # NaN where unset, on both sides
    np.testing.assert_array_equal(back.viseme, s.viseme)
    np.testing.assert_array_equal(back.expression, s.expression)


def test_write_and_read_a_file(tmp_path):
    s = parse_fap(EXAMPLE)
    path = write_fap(s, tmp_path / "x.fap")
    assert read_fap(path).values[1, 48] == 5000


@pytest.mark.parametrize("text, message", [
    ("", r"t.fap: the file has no header line"),
    ("2.1 demo 0 1\n", r"t.fap, line 1: frame rate 0 is not positive"),
    ("2.1 demo 25\n", r"t.fap, line 1: the header has 3 fields, expected 4"),
    (f"2.1 demo 25 1\n{MASK_3_49[:-2]}\n0 1\n", r"t.fap, line 2: expected 68 mask flags, found 67"),
    (f"2.1 demo 25 1\n{MASK_3_49}\n0 1\n",
     r"t.fap, line 3: frame 0: expected 3 numbers \(the frame number and 2 values for the 2 FAPs in the mask\), found 2"),
    (f"2.1 demo 25 1\n{MASK_3_49}\n0 1 x7\n", r"t.fap, line 3: value 'x7' is not a number"),
    (f"2.1 demo 25 1\n{MASK_3_49}\n", r"t.fap, line 2: the last mask line has no value line"),
    (f"2.1 demo 25 2\n{MASK_3_49}\n3 1 2\n{MASK_3_49}\n2 1 2\n", r"t.fap, line 5: frame number 2 does not follow frame 3"),
    (f"2.1 demo 25 1\n{MASK_3_49.replace('1', '2', 1)}\n0 1 2\n", r"line 2: mask flag '2' is not 0 or 1"),
])
def test_bad_files_name_the_line(text, message):
    with pytest.raises(InputError, match=message) as e:
        parse_fap(text, where="t.fap")
    assert "\n" not in str(e.value)


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="FAP stream not found"):
        read_fap(tmp_path / "none.fap")
