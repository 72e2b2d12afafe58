"""Greta's expression tables read as FAP values: intensities summed, sides kept, undeclared
units listed, bad files refused with the file named."""

from pathlib import Path

import pytest

from mpeg4.errors import InputError
from mpeg4.io.greta import BASIC_EXPRESSIONS, fap_side, read_action_units, read_expressions

GRETA = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "fap_streams" / "greta"

UNITS = """<?xml version="1.0" encoding="UTF-8"?>
<facelibrary>
  <actiondeclaration name="AU12">
    <fap num="12" value="150"/><fap num="13" value="130"/><fap num="5" value="100"/>
  </actiondeclaration>
  <actiondeclaration name="AU26"><fap num="3" value="400"/></actiondeclaration>
</facelibrary>
"""

EXPRESSIONS = """<?xml version="1.0" encoding="UTF-8"?>
<facelibrary>
  <expression class="faceexp" instance="smile">
    <action intensity="0.5" name="AU12"/>
    <action name="AU26"/>
    <action name="AU12" side="LEFT"/>
    <action name="AU9"/>
  </expression>
  <expression class="faceexp" instance="open"><action intensity="0.25" name="AU26"/></expression>
</facelibrary>
"""


def _library(folder: Path, units: str = UNITS, expressions: str = EXPRESSIONS) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "aulibrary.xml").write_text(units, encoding="utf-8")
    (folder / "facelibrary.xml").write_text(expressions, encoding="utf-8")
    return folder


def test_sides_follow_the_fap_names():
    assert fap_side(12) == "LEFT" and fap_side(13) == "RIGHT"
    assert fap_side(8) == "LEFT" and fap_side(57) == "LEFT" and fap_side(58) == "RIGHT"  # lm/rm: left/right middle
    assert fap_side(3) is None and fap_side(51) is None


def test_an_expression_is_the_sum_of_its_units_at_their_intensities(tmp_path):
    exp = read_expressions(_library(tmp_path))
    smile = exp["smile"]
    # 0.5 x AU12 on both sides, then AU12 again on the left only (its midlip FAP 5 belongs to no side).
    assert smile.values == {12: 0.5 * 150 + 150, 13: 0.5 * 130, 5: 0.5 * 100 + 100, 3: 400}
    assert smile.undeclared == ("AU9",)
    assert exp["open"].values == {3: 100.0}
    assert set(read_expressions(tmp_path, ["open"])) == {"open"}


@pytest.mark.parametrize("units, expressions, message", [
    (UNITS.replace('num="3"', 'num="70"'), EXPRESSIONS, "is not one of 1..68"),
    (UNITS.replace('value="400"', 'value="a lot"'), EXPRESSIONS, "is not a number"),
    (UNITS, EXPRESSIONS.replace('intensity="0.25"', 'intensity="nan"'), "is not a finite number"),
    (UNITS, EXPRESSIONS.replace('side="LEFT"', 'side="UP"'), "neither LEFT nor RIGHT"),
    (UNITS.replace("</facelibrary>", ""), EXPRESSIONS, "not well-formed XML"),
])
def test_bad_tables_are_refused_naming_the_file(tmp_path, units, expressions, message):
    with pytest.raises(InputError, match=message) as e:
        read_expressions(_library(tmp_path, units, expressions))
    assert ".xml" in str(e.value)


def test_a_missing_expression_or_file_is_named(tmp_path):
    with pytest.raises(InputError, match=r"no expression named 'joy'.*choose among open, smile"):
        read_expressions(_library(tmp_path), ["joy"])
    with pytest.raises(InputError, match="not found"):
        read_action_units(tmp_path / "nowhere.xml")


@pytest.mark.skipif(not GRETA.exists(), reason=f"Greta's tables are not there ({GRETA})")
def test_gretas_basic_expressions():
    exp = read_expressions(GRETA, BASIC_EXPRESSIONS)
    assert set(exp) == set(BASIC_EXPRESSIONS)
    assert exp["joy"].values[12] > 0 and exp["joy"].values[59] > 0  # AU12: the lip corners up
    assert exp["surprise"].values[3] > 0  # AU26: the jaw drops
    assert exp["anger"].values[57] == pytest.approx(609)  # the lower lip's sum of units the README quotes
    assert "AU9" in exp["disgust"].undeclared
